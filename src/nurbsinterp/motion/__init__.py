"""Look-ahead motion for programs of many blocks (issue 29): blocks → segments → windowed plan → ticks."""

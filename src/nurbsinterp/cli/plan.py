"""`nurbsinterp plan` (filled in by the plan issue)."""

"""`python -m nurbsinterp`: the same as the `nurbsinterp` command."""
from nurbsinterp._entry import main

main()

"""`python -m stewart_sim` is the `stewart-sim` command."""
import sys

from stewart_sim.cli import main

sys.exit(main())

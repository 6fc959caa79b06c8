"""`python -m flip_tools.cli ...`: the flip command (how flip starts its own recorder and runs)."""
import sys

from .main import main

sys.exit(main())

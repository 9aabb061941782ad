"""``python -m shadowflow.nodes.app.cli``."""
import sys

from . import main

sys.exit(main())

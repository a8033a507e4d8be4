"""``python -m agrisim`` is the ``agrisim`` command."""

import sys

from agrisim.cli import main

sys.exit(main())

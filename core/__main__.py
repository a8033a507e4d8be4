"""``python -m agrisim`` is the ``agrisim`` command."""

import sys

from agrisim.app.cli import main

sys.exit(main())

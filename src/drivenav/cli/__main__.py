"""``python -m drivenav.cli``: the ``drivenav`` command."""

import sys

from drivenav.cli import main

sys.exit(main())

"""``python -m mjsound.cli ...`` is ``mjsound ...``."""

import sys

from . import main

sys.exit(main())

"""``python -m gracenav.cli``."""

from __future__ import annotations

import sys

from gracenav.cli import main

sys.exit(main())

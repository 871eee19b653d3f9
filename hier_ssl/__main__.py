"""``python -m hier_ssl``: the ``hier-ssl`` command."""

from __future__ import annotations

import sys

from hier_ssl.cli import main

sys.exit(main())

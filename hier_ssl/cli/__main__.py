"""``python -m hier_ssl.cli``: the same command as ``hier-ssl``."""

import sys

from hier_ssl.cli import main

sys.exit(main())

"""``python -m sunlab.cli``: the ``sunlab`` command line.

Examples
--------
>>> import subprocess, sys
>>> subprocess.run([sys.executable, "-m", "sunlab.cli", "--version"],
...                capture_output=True).returncode
0
"""

import sys

from .commands import main

__all__: list[str] = []

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

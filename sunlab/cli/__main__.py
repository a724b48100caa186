"""``python -m sunlab.cli``: the ``sunlab`` command line.

Examples
--------
>>> import subprocess, sys
>>> subprocess.run([sys.executable, "-m", "sunlab.cli", "--version"],
...                capture_output=True).returncode
0
"""

from ._app import run

__all__: list[str] = []

if __name__ == "__main__":  # pragma: no cover
    run()

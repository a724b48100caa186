"""``python -m sunlab``: the ``sunlab`` command line (the same as the console script).

Examples
--------
>>> import subprocess, sys
>>> subprocess.run([sys.executable, "-m", "sunlab", "--version"],
...                capture_output=True).returncode
0
"""

from .cli import run

__all__: list[str] = []

if __name__ == "__main__":  # pragma: no cover
    run()

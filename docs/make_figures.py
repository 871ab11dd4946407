"""Regenerate every figure in docs/ (run from anywhere: python docs/make_figures.py).

Each figure is what its caption's command draws:

* ``docs/priorities.png``:
  ``qpik reach tasks/planar_4r_priorities.toml --plot docs/priorities.png``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIGURES = {
    "docs/priorities.png": ["reach", "tasks/planar_4r_priorities.toml", "--plot"],
}


def main() -> None:
    for figure, command in FIGURES.items():
        code = "import sys; from qpik.cli import main; sys.exit(main(sys.argv[1:]))"
        args = [sys.executable, "-c", code, *command, figure, "--quiet"]
        subprocess.run(args, cwd=ROOT, check=True)
        print(figure)


if __name__ == "__main__":
    main()

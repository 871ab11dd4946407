"""Regenerate every figure in docs/ (run from anywhere: ``python docs/make_figures.py``).

Each figure is what its caption's command draws (``--out DIR`` writes them elsewhere,
``--only NAME ...`` draws some of them):

* ``priorities.png``: ``qpik reach tasks/planar_4r_priorities.toml --plot priorities.png``;
* ``self_motion.png``: ``python examples/self_motion_4r.py --plot self_motion.png``;
* ``talos.png``: ``qpik reach tasks/talos_both_hands.toml --plot talos.png``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CLI = "import sys; from qpik.cli import main; sys.exit(main(sys.argv[1:]))"
#: Figure file name -> the command that draws it (the output path is appended).
FIGURES: dict[str, list[str]] = {
    "priorities.png": ["-c", CLI, "reach", "tasks/planar_4r_priorities.toml", "--quiet", "--plot"],
    "self_motion.png": ["examples/self_motion_4r.py", "--plot"],
    "talos.png": ["-c", CLI, "reach", "tasks/talos_both_hands.toml", "--quiet", "--plot"],
}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="folder of the figures")
    parser.add_argument("--only", nargs="+", choices=sorted(FIGURES), help="draw these only")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.only or FIGURES:
        target = (args.out / name).resolve()
        subprocess.run(
            [sys.executable, *FIGURES[name], str(target)],
            cwd=ROOT,
            check=True,
            stdout=subprocess.DEVNULL,
        )
        print(target)


if __name__ == "__main__":
    main()

"""Render docs/shaders.png: the sphere scene after 2 s, drawn by every shader of
the library in one labelled 3x3 sheet of 220x220 tiles. Headless (an EGL
context); well under a minute once the kernels are cached.

    python examples/make_shader_sheet.py [OUT.png]   (default: docs/shaders.png)
"""

from __future__ import annotations

import sys
from pathlib import Path

from clothsim.cli import main

OUT = Path(__file__).resolve().parent.parent / "docs" / "shaders.png"


if __name__ == "__main__":
    out = sys.argv[1] if len(sys.argv) > 1 else str(OUT)
    sys.exit(main(["render", "sphere", "--seconds", "2", "--shader", "all", "--size", "220x220",
                   "--no-progress", "--overwrite", "-o", out]))

"""Regenerate demo-quicklook.png and demo-seams.png of docs/user-guide/demo.md.

Run from the repository root: ``python docs/user-guide/img/make_demo_images.py [OUTDIR]``.
Runs the small demo into OUTDIR (default: a temporary directory; an OUTDIR holding a demo's
``quicklook.png`` and ``seams.png`` is used as it is), then reduces its two figures for the
page: resampled to 700 and 800 px wide and reduced to a palette of 96 and 48 colours
(Pillow, which matplotlib installs), about 130 KB together.
"""

import sys
import tempfile
from pathlib import Path

from PIL import Image

from geoblock.workflows import run_demo

HERE = Path(__file__).resolve().parent
SIZES = {"quicklook.png": ("demo-quicklook.png", 700, 96),
         "seams.png": ("demo-seams.png", 800, 48)}


def reduce(source: Path, target: Path, width: int, colours: int) -> None:
    image = Image.open(source).convert("RGB")
    height = round(image.height * width / image.width)
    small = image.resize((width, height), Image.Resampling.LANCZOS).quantize(
        colors=colours, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    small.save(target, optimize=True)
    print(f"{target}: {target.stat().st_size // 1024} KB")


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        outdir = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tmp) / "demo"
        if not all((outdir / name).is_file() for name in SIZES):
            run_demo(outdir, progress=print)
        for name, (target, width, colours) in SIZES.items():
            reduce(outdir / name, HERE / target, width, colours)


if __name__ == "__main__":
    main()

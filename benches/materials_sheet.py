"""One contact sheet of scanned material sets after `benches/materials.py` (fits) and
`benches/materials_train.py` (trainings): a row per set, and in each row the scan's colour map,
the fitted tile's colour laid 2x2, the fitted material lit, a trained sample's colour, the
trained material lit and the `texture-synthesis` crate's sample of the colour map. A set missing
from one of the two folders leaves its cells blank.

    python3 benches/materials_sheet.py SETS_DIR FIT_DIR TRAIN_DIR OUT.jpg [CELL_PX]
"""

import sys
from pathlib import Path

from PIL import Image, ImageDraw

COLUMNS = ["scan", "fit 2x2", "fit lit", "trained", "trained lit", "texture-synthesis"]


def first(folder, pattern):
    found = sorted(folder.glob(pattern)) if folder.is_dir() else []
    return found[0] if found else None


def tiled(path):
    """The tile laid 2x2, as a user repeats it."""
    tile = Image.open(path).convert("RGB")
    w, h = tile.size
    out = Image.new("RGB", (2 * w, 2 * h))
    for x in (0, w):
        for y in (0, h):
            out.paste(tile, (x, y))
    return out


def cells(name, sets, fits, trains):
    scan = first(sets / name, "color.*")
    fit_colour = first(fits / name, "*color*.png")
    samples = trains / f"{name}-samples"
    return [
        scan and Image.open(scan),
        fit_colour and tiled(fit_colour),
        (fits / f"{name}-lit.png").is_file() and Image.open(fits / f"{name}-lit.png"),
        first(samples, "s0-color.png") and Image.open(samples / "s0-color.png"),
        (trains / f"{name}-lit.png").is_file() and Image.open(trains / f"{name}-lit.png"),
        first(samples, "ts0.png") and Image.open(samples / "ts0.png"),
    ]


def main(argv):
    if len(argv) < 4:
        print(__doc__.strip())
        return 2
    sets, fits, trains, out = (Path(a) for a in argv[:4])
    cell = int(argv[4]) if len(argv) > 4 else 160
    names = sorted(p.name for p in sets.iterdir() if p.is_dir())
    label, margin = 16, 110
    sheet = Image.new("RGB", (margin + cell * len(COLUMNS), label + cell * len(names)), "white")
    draw = ImageDraw.Draw(sheet)
    for c, title in enumerate(COLUMNS):
        draw.text((margin + c * cell + 4, 2), title, fill="black")
    for r, name in enumerate(names):
        y = label + r * cell
        draw.text((4, y + cell // 2 - 6), name[:17], fill="black")
        for c, image in enumerate(cells(name, sets, fits, trains)):
            if image:
                # The scan's aspect is kept: a 2:1 set shows as a 2:1 thumbnail.
                image = image.convert("RGB")
                image.thumbnail((cell - 2, cell - 2), Image.LANCZOS)
                sheet.paste(image, (margin + c * cell + 1, y + 1))
    sheet.save(out, quality=82)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

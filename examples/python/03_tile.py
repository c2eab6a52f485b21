"""The guide's seamless tiles (docs/guide/synth.md), from Python.

`python examples/python/03_tile.py` paints a 256x256 tile of the shipped honeycomb and shows
that it repeats: the tile painted 2x2 is the tile laid 2x2. Writes `03_tile.png` (laid 2x2) and
`03_mirror.png`.
"""

import numpy as np

import ipfn

model = ipfn.load()
tile = model.paint(256, 256, seed=3, tile=True)
laid = np.tile(tile, (2, 2, 1))
# Column 0 continues column 255: the step across the seam is like any other step.
seam = np.abs(tile[:, 0] - tile[:, -1]).mean()
inside = np.abs(tile[:, 1:] - tile[:, :-1]).mean()
print(f"mean step across the seam {seam:.4f}, inside the tile {inside:.4f}")
ipfn.write_image("03_tile.png", laid)
ipfn.write_image("03_mirror.png", model.paint(256, 256, seed=3, mirror=True))
print("wrote 03_tile.png and 03_mirror.png")

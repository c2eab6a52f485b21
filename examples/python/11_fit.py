"""The guide's "`ipfn fit`: a photo into a seamless tile" (docs/guide/fit.md), from Python.

`python examples/python/11_fit.py` fits a seamless tile to the shipped honeycomb photo for 200
steps in `runs/11_fit_py/`, prints its PSNR and seam score, and paints the tile at twice its
resolution: `11_fit.png`.
"""

import ipfn

report = ipfn.fit("exemplars/honeycomb.png", iterations=200, run="runs/11_fit_py")
print(f"PSNR {report['psnr']:.2f} dB, seam score 2x2 {report['seam_tile']['overall']:.3f} "
      f"(the photo's own: {report['seam_photo']['overall']:.3f})")
tile = ipfn.load(report["model"])
ipfn.write_image("11_fit.png", tile.paint(512, 512))
print(f"wrote {', '.join(report['images'])} and 11_fit.png")

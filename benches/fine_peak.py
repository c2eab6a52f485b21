"""How sharply one fine period stands out in an image's spectrum: a number for the fine hatch
that samples of photos with no period carry and the photos lack.

    python3 benches/fine_peak.py IMAGE [IMAGE ...]

For each image: the luminance, its mean removed, under a Hann window; its power spectrum; in
each of 12 rings of frequency between periods of 16 and 4 pixels, the strongest bin over the
ring's median. The table gives the largest of those ratios and where it stands (the period
along rows and along columns, in pixels; `-` where the bin lies on an axis). A regular dot
lattice makes one bin tower over its ring; grain, veins and cracks spread their power. It is a
diagnostic for the experiment pages, not a measure `ipfn eval` reports: one sample's number
moves with the sample, and a straight line across a photo (a leaf's midrib) also raises it.
"""

import sys

import numpy as np
from PIL import Image

SHORTEST, LONGEST, RINGS = 4.0, 16.0, 12


def fine_peak(path):
    a = np.asarray(Image.open(path).convert("L"), dtype=np.float64)
    a -= a.mean()
    h, w = a.shape
    power = np.abs(np.fft.fft2(a * np.outer(np.hanning(h), np.hanning(w)))) ** 2
    fy, fx = np.meshgrid(np.fft.fftfreq(h), np.fft.fftfreq(w), indexing="ij")
    radius = np.hypot(fy, fx)
    edges = np.linspace(1 / LONGEST, 1 / SHORTEST, RINGS + 1)
    best = (0.0, 0.0, 0.0)
    for lo, hi in zip(edges[:-1], edges[1:]):
        ring = (radius >= lo) & (radius < hi)
        values = power[ring]
        i = int(np.argmax(values))
        ratio = values[i] / np.median(values)
        if ratio > best[0]:
            best = (ratio, fy[ring][i], fx[ring][i])
    return best


def period(f):
    return "-" if f == 0 else f"{1 / abs(f):.1f}"


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print("| image | peak / ring median | period along rows, columns (px) |")
    print("|---|---|---|")
    for path in sys.argv[1:]:
        ratio, fy, fx = fine_peak(path)
        print(f"| {path} | {ratio:.1f} | {period(fy)}, {period(fx)} |")


if __name__ == "__main__":
    main()

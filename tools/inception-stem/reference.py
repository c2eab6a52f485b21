#!/usr/bin/env python3
"""Turns reference.js's features into tests/data/sifid/expected.json.

SIFID here follows SinGAN's definition: each spatial position is a sample; the Gaussians have
the sample mean and np.cov's unbiased covariance; the distance is
|mu1 - mu2|^2 + tr(S1) + tr(S2) - 2 tr(sqrtm(S1 S2)) with scipy's general (Schur) sqrtm, as
SinGAN computes it. This shares no code with ipfn (which uses a symmetric eigendecomposition).

    python3 reference.py /tmp/sifid-ref ../../tests/data/sifid/expected.json
"""
import json
import sys

import numpy as np
import scipy
from scipy import linalg


def gaussian(features):
    return features.mean(axis=0), np.cov(features, rowvar=False)


def frechet(a, b):
    (m1, s1), (m2, s2) = a, b
    root = linalg.sqrtm(s1.dot(s2))
    root = np.real(root)
    d = m1 - m2
    return float(d.dot(d) + np.trace(s1) + np.trace(s2) - 2.0 * np.trace(root))


def main(ref_dir, out):
    names = ["honeycomb_a", "honeycomb_b", "bricks"]
    feats = {n: np.load(f"{ref_dir}/{n}.npy").astype(np.float64) for n in names}
    g = {n: gaussian(f) for n, f in feats.items()}
    probe = [0, 1, 29, 400, 783]  # feature positions (row-major in the 28x28 map)
    expected = {
        "about": "Made by tools/inception-stem/reference.js (tfjs 4.22.0 running the Keras model "
        "from nsfwjs@4.4.0) and reference.py (numpy " + np.__version__ + ", scipy "
        + scipy.__version__ + "). Do not edit by hand; rerun the scripts (README.md there).",
        "inputs": {
            "honeycomb_a": ["exemplars/honeycomb.png", 0, 0, 128],
            "honeycomb_b": ["exemplars/honeycomb.png", 128, 96, 128],
            "bricks": ["exemplars/bricks.png", 0, 0, 128],
        },
        "feature_shape": [28, 28, 192],
        "channel_means": {n: f.mean(axis=0).tolist() for n, f in feats.items()},
        "probe_positions": probe,
        "probe_features": {n: f[probe].tolist() for n, f in feats.items()},
        "sifid": {
            "honeycomb_a/honeycomb_a": frechet(g["honeycomb_a"], g["honeycomb_a"]),
            "honeycomb_a/honeycomb_b": frechet(g["honeycomb_a"], g["honeycomb_b"]),
            "honeycomb_a/bricks": frechet(g["honeycomb_a"], g["bricks"]),
        },
    }
    with open(out, "w") as f:
        json.dump(expected, f, indent=1)
        f.write("\n")
    print(json.dumps(expected["sifid"], indent=1))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])

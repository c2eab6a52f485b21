"""The guide's "`ipfn train`: learn a pattern" (docs/guide/train.md), from Python.

`python examples/python/02_train.py` trains on the shipped honeycomb exemplar for 60
iterations in `runs/02_train_py/` (about a minute on 2 cores), printing progress at each
checkpoint, then paints `02_train.png` with the run's best model. `time="15m"` (the default)
trains as `ipfn train` does.
"""

import ipfn


def progress(p):
    if p["sifid"] is not None:
        print(f"iteration {p['iteration']}/{p['iterations']}: SIFID {p['sifid']:.2f}, "
              f"structure {p['structure']:.3f}")
    return True  # False would stop the run after a checkpoint


model = ipfn.train("exemplars/honeycomb.png", out="runs/02_train_py", iterations=60,
                   checkpoint_every=20, on_progress=progress)
ipfn.write_image("02_train.png", model.paint(256, 256, seed=1))
print(f"trained to iteration {model.iteration}; wrote 02_train.png")

"""The guide's "`ipfn synth`: paint a sample" (docs/guide/synth.md), from Python.

`python examples/python/01_synth.py` paints a 512x512 seamless tile of the shipped honeycomb,
the same values as `ipfn synth --size 512 --seed 7 --tile --out 01_synth.npy`, and writes
`01_synth.png`.
"""

import ipfn

model = ipfn.load()  # the shipped honeycomb; ipfn.load("runs/NAME") for a run's best model
image = model.paint(512, 512, seed=7, tile=True)  # float32 [512, 512, 3] in [-1, 1]
print(f"{model.kind} model, period {model.period} px: painted {image.shape}")
ipfn.write_image("01_synth.png", image)
print("wrote 01_synth.png")

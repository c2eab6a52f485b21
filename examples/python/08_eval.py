"""The guide's "`ipfn eval`: how good is a model" (docs/guide/eval.md), from Python.

`python examples/python/08_eval.py` scores the shipped honeycomb model against the shipped
exemplar over 2 samples: the dict `ipfn eval --json` prints.
"""

import ipfn

report = ipfn.evaluate(ipfn.load(), "exemplars/honeycomb.png", samples=2)
print(f"SIFID {report['sifid']['mean']:.2f} ± {report['sifid']['std']:.2f}")
print(f"structure {report['structure']['mean']:.4f} (the exemplar's floor "
      f"{report['structure_floor']:.4f})")
print(f"seam score of tiles laid 2x2 {report['seam_model_tile']['overall']:.3f}")
print(f"period {report['period_model']} px (rows, columns)")

"""identification: the dynamic model of eq. 1 from js2 logs (offline; imports js2spec, numpy, scipy, pinocchio,
filterpy, matplotlib — never js2io or hil_sim).

```python
from identification.pipeline import identify, IdentifyOptions     # the whole paper, logs -> Identification
from identification import output, report                          # model.yaml / URDF / verdict.json, report.html
ident = identify(["run.mcap"], IdentifyOptions(method="mixed"))
output.write_model(ident, outdir); output.write_urdf(ident, outdir); report.write_report(ident, outdir)
```

Modules: ``signals`` (K mapping, 50 Hz / 7 Hz zero-phase filters, lost cycles), ``sequential`` (static test eq. 2-4,
constant velocity eq. 5), ``trials`` (events -> segments, breakaways), ``regressor`` (eq. 1 linear in the
parameters, pinocchio + K^T + motor columns), ``base`` (base parameters by pivoted QR), ``estimators`` (RLS,
OLS/WLS: fit/predict/score), ``consistency`` (physically consistent standard parameters), ``reference`` (other
models on the same samples), ``importer`` (CSV/NumPy -> js2 log). CLIs: ``js2-identify``, ``js2-import``.
See docs/identification.md.
"""

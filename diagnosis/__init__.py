"""Model mismatch diagnosis: when a model and a recording disagree, locate the mismatch, name the physics the
model leaves out, model it, and show the fit improve on data that was not fitted.

    residual  (:mod:`diagnosis.residual`)   model.yaml + js2 log  ->  measured - predicted torque, per motor
    locate    (:mod:`diagnosis.locate`)     where the residual lives: which motor, which regime (speed, direction,
                                             reversals, time, motor angle)
    library   (:mod:`diagnosis.library`)    candidate physics terms, one per effect kind the simulator can hide
    search    (:mod:`diagnosis.search`)     fit each candidate on the fit data, score it on held-out data, accept
                                             the best while it improves the held-out fit (a nested-model ladder)
    report    (:mod:`diagnosis.report`)     diagnosis.json, model.yaml extended with ``unmodelled:``, report.html

The effect kinds and their parameters are those of ``hil_sim.effects`` (same names, same units), so a diagnosed
model can be simulated again with the physics it was missing.
"""

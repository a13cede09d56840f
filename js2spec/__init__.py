"""js2spec: the contracts every js2 part honours.

- :mod:`js2spec.drives` — the drive and transmission file (``drives.yaml``, keys of the js2 log spec v1).
- :mod:`js2spec.robot` — a robot described as data: a ``configs/<robot>/`` folder.
- :mod:`js2spec.log` — the js2 log (MCAP, spec v1): writer and reader.
- :mod:`js2spec.errors` — errors that name the file (and key) that was wrong.

Nothing here talks to a bus or runs physics; every other package may import it.
"""

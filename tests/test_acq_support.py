"""Shared by the acquisition tests: a short version of configs/js2/trials.yaml (same trials, fewer poses/axes,
shorter trajectories) so a `--trial all` run takes seconds."""
from __future__ import annotations

from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]


def short_trials_yaml(dest: Path) -> Path:
    c = yaml.safe_load((ROOT / "configs" / "js2" / "trials.yaml").read_text())
    c["static"].update(poses=[c["static"]["poses"][1]], axes=[1, 4])
    c["velocity"].update(axes=[2, 5], speed_fractions=[0.2, 1.0], steady_s=0.3)
    c["acceleration"].update(durations=[1.2], strokes_per_duration=2)
    c["excitation"].update(period_s=2.0, periods=1, harmonics=3, fade_s=0.4)
    c["validation"].update(period_s=2.0, periods=1, harmonics=3, fade_s=0.4)
    dest.write_text(yaml.safe_dump(c))
    return dest

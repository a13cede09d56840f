"""`js2-acquire --trial all` against the in-process simulator (CANopen on python-can's virtual bus), and its log
checked against shared/spec/js2-log-v1.md with the `mcap` reader alone (no js2spec on the reading side)."""
from __future__ import annotations

import datetime as dt
import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

from test_acq_support import short_trials_yaml
from js2io.cli import main

EVENT_KINDS = {"trial_start", "trial_end", "segment_start", "segment_end", "breakaway", "fault", "abort"}
TRIALS = ["static", "velocity", "acceleration", "excitation", "validation"]


@pytest.fixture(scope="module")
def run_log(tmp_path_factory):
    d = tmp_path_factory.mktemp("conf")
    out = d / "run.mcap"
    rc = main(["--trial", "all", "-o", str(out), "--config", str(short_trials_yaml(d / "t.yaml")), "--no-progress",
               "--joint-state"])
    assert rc == 0
    return out


def _read(path):
    with open(path, "rb") as f:
        r = make_reader(f, validate_crcs=True)
        summary = r.get_summary()
        meta = {m.name: dict(m.metadata) for m in r.iter_metadata()}
        att = {a.name: a for a in r.iter_attachments()}
        msgs = [(ch.topic, sc, ch, m) for sc, ch, m in r.iter_messages()]
    return summary, meta, att, msgs


def test_file_metadata_attachments(run_log):
    summary, meta, att, msgs = _read(run_log)
    assert summary is not None, "no summary section (file not closed properly)"
    comp = {ci.compression for ci in summary.chunk_indexes}
    assert comp and comp <= {"zstd", "lz4"}, comp
    m = meta["js2"]
    assert m["format"] == "js2-log" and m["version"] == "1" and m["robot"] == "js2"
    assert float(m["cycle_hz"]) == 500.0
    assert m["source"].split(":")[0] in ("hardware", "hil_sim", "import") and m["source"].startswith("hil_sim")
    created = dt.datetime.fromisoformat(m["created"].replace("Z", "+00:00"))
    assert created.tzinfo is not None and created.utcoffset() == dt.timedelta(0)
    assert att["robot.urdf"].media_type == "application/xml"
    assert att["drives.yaml"].media_type == "application/yaml"
    urdf_joints = [j.get("name") for j in ET.fromstring(att["robot.urdf"].data).iter("joint")
                   if j.get("type") != "fixed"]
    dy = yaml.safe_load(att["drives.yaml"].data)
    n = len(dy["joints"])
    assert dy["joints"] == urdf_joints[:n] and n == 6
    assert np.asarray(dy["gear_ratio_matrix"]).shape == (n, n)
    for k in ("torque_constant", "encoder_counts_per_rev", "rated_torque", "rated_current"):
        assert len(dy[k]) == n, k
    assert dy["torque_side"] == "motor"
    # statistics agree with what is in the file
    counts = {}
    for topic, *_ in msgs:
        counts[topic] = counts.get(topic, 0) + 1
    assert summary.statistics.message_count == len(msgs)
    for cid, c in summary.statistics.channel_message_counts.items():
        assert counts[summary.channels[cid].topic] == c


def test_channels_and_messages(run_log):
    summary, meta, att, msgs = _read(run_log)
    dy = yaml.safe_load(att["drives.yaml"].data)
    n = len(dy["joints"])
    kt = np.asarray(dy["torque_constant"])
    cpr = np.asarray(dy["encoder_counts_per_rev"])
    lim = np.asarray(dy["limits"]["torque"])
    topics = {ch.topic: (ch, summary.schemas[ch.schema_id]) for ch in summary.channels.values()}
    for t in ("/js2/feedback", "/js2/command", "/js2/event"):
        ch, sc = topics[t]
        assert ch.message_encoding == "json" and sc.encoding == "jsonschema"
        json.loads(sc.data)
    t0 = min(m.log_time for *_, m in msgs)
    by = {"/js2/feedback": [], "/js2/command": [], "/js2/event": []}
    last_lt = {}
    for topic, sc, ch, m in msgs:
        assert m.publish_time == m.log_time
        assert m.log_time >= last_lt.get(topic, 0), f"{topic}: log_time goes back"
        last_lt[topic] = m.log_time
        d = json.loads(m.data)
        if topic != "/js2/joint_state":   # the viewer channel has no t field (spec)
            assert math.isclose(d["t"], (m.log_time - t0) / 1e9, abs_tol=2e-9), (topic, d["t"])
        if topic in by:
            by[topic].append(d)
    fb = by["/js2/feedback"]
    cyc = np.array([d["cycle"] for d in fb])
    assert len(fb) > 1000 and np.all(np.diff(cyc) == 1), "feedback cycles must count +1 per SYNC (no loss here)"
    for d in fb[::97]:
        for k in ("motor_position", "torque", "motor_current", "status", "valid"):
            assert len(d[k]) == n, k
        counts = np.asarray(d["motor_position"]) * cpr / (2 * np.pi)
        assert np.allclose(counts, np.round(counts), atol=1e-6), "motor_position = counts / cpr * 2 pi"
        assert np.allclose(d["torque"], kt * np.asarray(d["motor_current"]), atol=1e-9)
        assert all(isinstance(s, int) for s in d["status"]) and all(v is True for v in d["valid"])
    cmd = by["/js2/command"]
    assert len(cmd) > 1000
    fbc = set(cyc.tolist())
    for d in cmd:
        assert d["cycle"] in fbc and len(d["mode"]) == n and len(d["target_torque"]) == n
        assert all(abs(x) <= l + 1e-12 for x, l in zip(d["target_torque"], lim)), d
    assert {m for d in cmd for m in d["mode"]} == {10}
    js = [json.loads(m.data) for topic, _, _, m in msgs if topic == "/js2/joint_state"]
    assert len(js) == len(fb)
    K = np.asarray(dy["gear_ratio_matrix"])
    for d, f in list(zip(js, fb))[::211]:
        assert d["name"] == dy["joints"] and len(d["velocity"]) == n
        assert np.allclose(d["position"], K @ np.asarray(f["motor_position"]) + np.asarray(dy["joint_offset"]))
        assert np.allclose(d["effort"], np.linalg.solve(K.T, np.asarray(f["torque"])))


def test_events_structure(run_log):
    summary, meta, att, msgs = _read(run_log)
    ev = [json.loads(m.data) for topic, _, _, m in msgs if topic == "/js2/event"]
    assert all(e["kind"] in EVENT_KINDS for e in ev)
    assert not [e for e in ev if e["kind"] in ("fault", "abort")]
    starts = [e["trial"] for e in ev if e["kind"] == "trial_start"]
    ends = [e["trial"] for e in ev if e["kind"] == "trial_end"]
    assert starts == TRIALS and ends == TRIALS
    ts = [e["t"] for e in ev]
    assert ts == sorted(ts)
    for trial in TRIALS:
        mine = [e for e in ev if e["trial"] == trial]
        segs = [e for e in mine if e["kind"] in ("segment_start", "segment_end")]
        assert segs and len(segs) % 2 == 0, trial
        for a, b in zip(segs[::2], segs[1::2]):
            assert a["kind"] == "segment_start" and b["kind"] == "segment_end" and b["t"] > a["t"], trial
            if trial == "static":
                assert a["joint"] in range(6) and a["direction"] in (1, -1) and len(a["pose"]) == 6
            if trial == "velocity":
                assert a["joint"] in range(6) and a["direction"] in (1, -1) and a["speed"] > 0
                assert (a["joint"], a["direction"], a["speed"]) == (b["joint"], b["direction"], b["speed"])
    br = [e for e in ev if e["kind"] == "breakaway"]
    assert len(br) == 4   # 1 pose x 2 axes x 2 directions (short config)
    for e in br:
        assert e["trial"] == "static" and e["joint"] in (1, 4) and e["direction"] in (1, -1)
        assert isinstance(e["value"], float) and len(e["pose"]) == 6
    # both speeds and both directions of each velocity axis
    vel = {(e["joint"], e["direction"], round(e["speed"], 6)) for e in ev
           if e["trial"] == "velocity" and e["kind"] == "segment_start"}
    assert len(vel) == 2 * 2 * 2

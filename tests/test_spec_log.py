"""The js2 log writer and reader against the spec: round trip, truncation recovery, refusals."""
import json

import numpy as np
import pytest
from mcap.writer import Writer

from js2spec.errors import LogError
from js2spec.log import LogWriter, read_log
from js2spec.robot import load_robot


@pytest.fixture(scope="module")
def robot():
    return load_robot("js2")


def _write(path, robot, n_cycles=2000, nan_at=None, gap_at=None, start_ns=None):
    rng = np.random.default_rng(1)
    pos = rng.normal(size=(n_cycles, 6))
    with LogWriter(path, robot="js2", cycle_hz=500, source="hil_sim:test", urdf_text=robot.urdf_text,
                   drives_yaml=robot.drives_yaml, start_ns=start_ns) as w:
        w.event(0.0, "trial_start", "static")
        w.event(0.0, "segment_start", "static", joint=1, direction=1, pose=[0.0] * 6)
        for k in range(n_cycles):
            if gap_at is not None and k == gap_at:
                continue
            p = pos[k].copy()
            if nan_at is not None and k == nan_at:
                p[2] = np.nan
            w.feedback(k, k / 500, p, torque=p * 0.1, motor_current=p, status=[0x27] * 6)
            w.command(k, k / 500, 10, p * 0.01)
        w.event((n_cycles - 1) / 500, "breakaway", "static", joint=1, direction=1, value=0.031)
        w.event((n_cycles - 1) / 500, "segment_end", "static", joint=1)
        w.event((n_cycles - 1) / 500, "trial_end", "static")
    return pos


def test_round_trip(tmp_path, robot):
    path = tmp_path / "a.mcap"
    pos = _write(path, robot)
    log = read_log(path)
    assert not log.truncated and log.robot == "js2" and log.cycle_hz == 500
    np.testing.assert_array_equal(log.feedback.motor_position, pos)
    np.testing.assert_array_equal(log.feedback.cycle, np.arange(2000))
    assert log.command.target_torque.shape == (2000, 6) and np.all(log.command.mode == 10)
    assert [e["kind"] for e in log.events].count("breakaway") == 1
    seg, t_end = log.segments("static")[0]
    assert seg["joint"] == 1 and seg["pose"] == [0.0] * 6 and t_end == pytest.approx(1999 / 500)
    assert log.drives.K.shape == (6, 6) and "<robot" in log.urdf_text
    assert len(log.sha256) == 64


def test_truncated_log_is_recovered_and_says_so(tmp_path, robot):
    path = tmp_path / "a.mcap"
    pos = _write(path, robot, n_cycles=6000)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    log = read_log(cut)
    assert log.truncated and "truncated" in log.recovered_note
    n = len(log.feedback)
    assert 1000 < n < 6000
    np.testing.assert_array_equal(log.feedback.motor_position, pos[:n])


def _chunk_offsets(path):
    """Byte offsets of the file's chunks, from its own chunk index (mcap's seeking reader)."""
    from mcap.reader import make_reader
    with open(path, "rb") as f:
        return sorted(ci.chunk_start_offset for ci in make_reader(f).get_summary().chunk_indexes)


@pytest.mark.parametrize("start_ns", [None, 1795045347657007361, 1795046604405007565])
def test_corrupt_chunk_mid_file_is_skipped_and_named(tmp_path, robot, start_ns):
    """64 zero bytes inside a chunk at a third of the file: that chunk is skipped, everything after it is read,
    and the reader says where and how much was lost (not 'truncated'). The two fixed start times are ones where
    the zeros right after a 0x06 byte read as an empty chunk with no CRC (mcap_scan._whole_chunk): the scan took
    it, reported two damages, and once (CI, stop 29) jumped over 3.7 s of intact messages."""
    path = tmp_path / "a.mcap"
    pos = _write(path, robot, n_cycles=6000, start_ns=start_ns)
    data = bytearray(path.read_bytes())
    offs = _chunk_offsets(path)
    bad = next(o for o in offs if o > len(data) // 3)
    data[bad + 40:bad + 104] = bytes(64)
    hurt = tmp_path / "hurt.mcap"
    hurt.write_bytes(bytes(data))
    log = read_log(hurt)
    assert not log.truncated and len(log.damage) == 1 and log.damage[0].kind == "corrupt"
    assert f"corrupt bytes {bad}.." in log.recovered_note and "s of messages lost" in log.recovered_note
    n = len(log.feedback)
    lost = 6000 - n
    assert 0 < lost < 6000 * 0.05, lost          # one small chunk, not two thirds of the file
    idx = np.flatnonzero(np.diff(log.feedback.cycle) > 1)
    assert len(idx) == 1                          # one hole, where the chunk was
    keep = np.r_[np.arange(idx[0] + 1), np.arange(idx[0] + 1 + lost, 6000)]
    np.testing.assert_array_equal(log.feedback.motor_position, pos[keep])
    assert log.events[-1]["kind"] == "trial_end"  # the events written after the damage are there


def test_garbage_after_damage_never_becomes_data(tmp_path, robot):
    """Random bytes over the whole second half: what is read is exactly a prefix of what was written."""
    path = tmp_path / "a.mcap"
    pos = _write(path, robot, n_cycles=4000)
    data = bytearray(path.read_bytes())
    rng = np.random.default_rng(3)
    half = len(data) // 2
    data[half:] = rng.integers(0, 256, len(data) - half, dtype=np.uint8).tobytes()
    hurt = tmp_path / "garbage.mcap"
    hurt.write_bytes(bytes(data))
    log = read_log(hurt)
    n = len(log.feedback)
    assert 0 < n < 4000 and log.recovered_note
    np.testing.assert_array_equal(log.feedback.motor_position, pos[:n])


def test_js2_repair_makes_a_killed_log_complete(tmp_path, robot, capsys):
    """A log cut off as by kill -9 (no footer): mcap's own reader yields nothing from it; after js2-repair it
    yields every message that was recoverable, and read_log says the log was repaired."""
    from mcap.reader import make_reader

    from js2spec.repair import main as repair_main
    path = tmp_path / "a.mcap"
    pos = _write(path, robot, n_cycles=6000)
    data = path.read_bytes()
    cut = tmp_path / "killed.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    n_before = len(read_log(cut).feedback)
    assert repair_main([str(cut)]) == 0
    out = tmp_path / "killed.repaired.mcap"
    assert "truncated" in capsys.readouterr().out
    with open(out, "rb") as f:
        r = make_reader(f)
        n_fb = sum(1 for _, ch, _ in r.iter_messages(topics=["/js2/feedback"]))
        assert r.get_summary() is not None
    assert n_fb == n_before
    log = read_log(out)
    assert not log.truncated and "repaired by js2-repair" in log.recovered_note
    np.testing.assert_array_equal(log.feedback.motor_position, pos[:n_before])
    assert log.attachments.keys() >= {"robot.urdf", "drives.yaml"}
    # refusals: one line, exit 2
    for argv, what in (([str(cut)], "exists; pass --force"), ([str(tmp_path)], "is a folder"),
                       ([str(tmp_path / "none.mcap")], "file not found"), ([str(cut), "-o", str(cut)], "itself")):
        assert repair_main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and what in err, err


def test_a_folder_given_as_log_is_named_a_folder(tmp_path):
    with pytest.raises(LogError, match="is a folder"):
        read_log(tmp_path)


def test_gaps_and_nans_are_reported_not_hidden(tmp_path, robot):
    path = tmp_path / "a.mcap"
    _write(path, robot, nan_at=100, gap_at=50)
    log = read_log(path)
    assert log.lost_cycles == 1
    assert not log.feedback.valid[99, 2] and log.feedback.valid[99, 1]  # cycle 100 is row 99 after the gap
    assert any("NaN" in w for w in log.warnings)
    assert np.isnan(log.feedback.motor_position[99, 2])   # the NaN literal orjson refuses, read by Python's json


def test_fast_decoder_reads_every_float_as_pythons_json_does(tmp_path):
    """orjson decodes the messages (js2spec.log._decode_all): to the last bit the numbers Python's json reads, on
    floats of every size the drives write (repr round trip), subnormals and integers included."""
    from js2spec.log import _decode_all
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.normal(size=3000) * 10.0 ** rng.integers(-300, 300, 3000), [5e-324, 2.2e-308, -0.0,
                        1.7976931348623157e308, 0.1, 1 / 3]])
    raws = [json.dumps({"t": float(v), "cycle": int(i), "torque": [float(v), 1e-4 * i]}).encode()
            for i, v in enumerate(x)]
    fast = _decode_all(tmp_path, raws, "/js2/feedback")
    slow = json.loads(b"[" + b",".join(raws) + b"]")
    assert fast == slow
    assert all(np.float64(a["t"]).tobytes() == np.float64(b["t"]).tobytes() for a, b in zip(fast, slow))
    with_nan = raws + [b'{"t": NaN, "cycle": 1, "torque": [Infinity, 0.0]}']
    assert np.isnan(_decode_all(tmp_path, with_nan, "/js2/feedback")[-1]["t"])
    with pytest.raises(LogError, match="message #2 is not valid JSON"):
        _decode_all(tmp_path, raws[:2] + [b"{"], "/js2/feedback")


def test_refuses_non_mcap(tmp_path):
    p = tmp_path / "x.mcap"
    p.write_text("hello")
    with pytest.raises(LogError, match=r"x.mcap: not an MCAP file"):
        read_log(p)


def _raw_mcap(path, meta, attachments=(), feedback=None):
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        if meta is not None:
            w.add_metadata("js2", meta)
        for name, data in attachments:
            w.add_attachment(0, 0, name, "text/plain", data)
        if feedback is not None:
            sid = w.register_schema("x", "jsonschema", b"{}")
            cid = w.register_channel("/js2/feedback", "json", sid)
            for i, msg in enumerate(feedback):
                w.add_message(cid, log_time=i, publish_time=i, data=json.dumps(msg).encode())
        w.finish()


def test_refuses_wrong_version_missing_parts_and_bad_arrays(tmp_path, robot):
    meta = {"format": "js2-log", "version": "1", "robot": "js2", "cycle_hz": "500", "source": "x",
            "created": "2026-11-22T00:00:00Z"}
    att = [("robot.urdf", robot.urdf_text.encode()), ("drives.yaml", robot.drives_yaml.encode())]
    good = {"cycle": 0, "t": 0.0, "motor_position": [0.0] * 6, "torque": [0.0] * 6, "motor_current": [0.0] * 6}
    cases = [
        (None, att, [good], "no 'js2' metadata"),
        ({**meta, "version": "2"}, att, [good], "version '2' is not supported"),
        (meta, att[:1], [good], "attachment 'drives.yaml' is missing"),
        (meta, att, None, "channel /js2/feedback is missing"),
        (meta, att, [{**good, "torque": [0.0] * 5}], "drives.yaml lists 6 joints"),
    ]
    for i, (m, a, fb, msg) in enumerate(cases):
        p = tmp_path / f"bad{i}.mcap"
        _raw_mcap(p, m, a, fb)
        with pytest.raises(LogError) as err:
            read_log(p)
        assert msg in str(err.value) and str(p) in str(err.value)


def test_damage_notes_name_the_damaged_logs(tmp_path, robot):
    from js2spec.log import damage_notes
    good = tmp_path / "good.mcap"
    _write(good, robot, n_cycles=3000)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(good.read_bytes()[:len(good.read_bytes()) // 2])
    notes = damage_notes([good, cut, tmp_path / "missing.mcap"])
    assert len(notes) == 1 and notes[0].startswith(f"{cut}: truncated")
    # files that are not MCAP at all (wrong magic bytes) get no note: nothing was lost from them, and "truncated:
    # ... every record in it is complete" would contradict read_log's "not an MCAP file"
    others = {"random.mcap": np.random.default_rng(3).integers(0, 256, 4096, dtype=np.uint8).tobytes(),
              "text.mcap": b"time,q1,q2\n0.0,0.1,0.2\n", "short.mcap": b"abc",
              "magic_only.mcap": good.read_bytes()[:8]}
    for name, data in others.items():
        (tmp_path / name).write_bytes(data)
    notes = damage_notes([tmp_path / name for name in others] + [cut])
    assert len(notes) == 2 and all(n.startswith(f"{tmp_path / 'magic_only.mcap'}: truncated") or
                                   n.startswith(f"{cut}: truncated") for n in notes), notes


def test_join_logs_makes_one_session_of_several_files(tmp_path, robot):
    from js2spec.log import join_logs

    _write(tmp_path / "a.mcap", robot, n_cycles=300)
    _write(tmp_path / "b.mcap", robot, n_cycles=200)
    a, b = read_log(tmp_path / "a.mcap"), read_log(tmp_path / "b.mcap")
    j = join_logs([a, b], gap_cycles=50)
    assert len(j.feedback) == 500 and j.meta["joined_from"].count(".mcap") == 2
    np.testing.assert_array_equal(j.feedback.motor_position[300:], b.feedback.motor_position)
    # the second file starts 50 cycles after the first ends, in time and in the cycle counter (a gap, not a loss)
    assert j.feedback.cycle[300] - j.feedback.cycle[299] == 50
    assert j.feedback.t[300] - j.feedback.t[299] == pytest.approx(50 / 500)
    assert np.all(np.diff(j.feedback.t) > 0)
    starts = [e["t"] for e in j.events if e["kind"] == "trial_start"]
    assert starts == pytest.approx([0.0, j.feedback.t[300]])
    # the files' commands are decoded when the joined session's are first read, not by the join
    assert not hasattr(a, "_command") and not hasattr(b, "_command")
    assert len(j.command) == 500 and j.command.t[300] == pytest.approx(j.feedback.t[300])
    np.testing.assert_array_equal(j.command.target_torque[300:], b.command.target_torque)
    assert join_logs([a]) is a


def test_join_logs_refuses_recordings_of_another_arm_or_rate(tmp_path, robot):
    from js2spec.log import join_logs

    _write(tmp_path / "a.mcap", robot, n_cycles=100)
    with LogWriter(tmp_path / "c.mcap", robot="js2", cycle_hz=250, source="hil_sim:test", urdf_text=robot.urdf_text,
                   drives_yaml=robot.drives_yaml) as w:
        for k in range(50):
            w.feedback(k, k / 250, np.zeros(6), torque=np.zeros(6), motor_current=np.zeros(6))
    with pytest.raises(LogError, match="cycle_hz differs"):
        join_logs([read_log(tmp_path / "a.mcap"), read_log(tmp_path / "c.mcap")])


def test_a_log_read_every_kth_cycle_is_what_a_slower_logger_writes(tmp_path, robot):
    """js2spec.resample.decimate_log: every 5th cycle of a 500 Hz log is a 100 Hz log of the same instants (the
    samples as read, no filter), cycles consecutive again, every event kept, and the log says where it came from."""
    from js2spec.resample import decimate_log

    path = tmp_path / "a.mcap"
    pos = _write(path, robot, n_cycles=2000)
    slow = read_log(decimate_log(path, tmp_path / "slow.mcap", 5))
    assert slow.cycle_hz == 100 and "every 5th cycle" in slow.meta["decimated_from"]
    np.testing.assert_array_equal(slow.feedback.motor_position, pos[::5])
    np.testing.assert_array_equal(slow.feedback.torque, pos[::5] * 0.1)
    np.testing.assert_array_equal(slow.feedback.cycle, np.arange(400))
    np.testing.assert_allclose(slow.feedback.t, np.arange(0, 2000, 5) / 500)
    np.testing.assert_array_equal(slow.command.target_torque, pos[::5] * 0.01)
    assert slow.command.target_velocity is None
    assert [e["kind"] for e in slow.events] == [e["kind"] for e in read_log(path).events]
    assert slow.segments("static")[0][0]["pose"] == [0.0] * 6
    for bad in (0, 2.5):
        with pytest.raises(ValueError, match="whole number"):
            decimate_log(path, tmp_path / "bad.mcap", bad)


def test_chunk_breakup_equals_mcaps_own_and_refuses_a_record_past_the_chunk(tmp_path, robot):
    """The scan's chunk reader (one unpack per message header) gives exactly mcap's ``breakup_chunk`` records --
    schemas, channels and messages, in order -- on every chunk of a js2 log; a message whose length runs past its
    chunk's end is refused instead of returned short."""
    import dataclasses
    import io

    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader, breakup_chunk

    from js2spec.mcap_scan import _breakup

    path = tmp_path / "a.mcap"
    _write(path, robot, n_cycles=3000)
    chunks = [r for r in StreamReader(io.BytesIO(path.read_bytes()), emit_chunks=True).records
              if isinstance(r, Chunk)]
    assert len(chunks) >= 2
    n = 0
    for chunk in chunks:
        ours, theirs = _breakup(chunk), breakup_chunk(chunk, validate_crc=True)
        assert ours == theirs
        n += len(ours)
    assert n > 6000               # 3000 feedback + 3000 command messages, the events and channels
    # a chunk whose last message says it is 100 bytes longer than the chunk holds
    data = b"".join([bytes([0x05]), (22 + 4 + 100).to_bytes(8, "little"), bytes(22), b"abcd"])
    bad = dataclasses.replace(chunks[0], data=data, compression="", uncompressed_size=len(data),
                              uncompressed_crc=0)
    with pytest.raises(ValueError, match="runs past"):
        _breakup(bad)

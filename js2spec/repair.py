"""js2-repair: rewrite a damaged js2 log (killed writer, corrupt chunk) as a complete MCAP any viewer opens.

  js2-repair session.mcap                       # -> session.repaired.mcap
  js2-repair session.mcap -o fixed.mcap --force

Every record that can be read (`js2spec.mcap_scan`) is copied: metadata, attachments, schemas, channels and messages,
with their log times and sequence numbers; the skipped regions are named on the terminal and in a `js2_repair`
metadata record, so every tool that reads the repaired log says it was repaired. Exit 0 repaired, 2 bad input.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import sys
from pathlib import Path

from .errors import Js2Error, LogError
from .mcap_scan import MCAP_MAGIC, McapScan


def repair(src: str | Path, dst: str | Path) -> McapScan:
    """Copy what `src` holds into a complete MCAP at `dst`; returns the scan (its `damage` says what was lost)."""
    from mcap.records import Attachment, Channel, Message, Metadata, Schema
    from mcap.writer import CompressionType, Writer

    src, dst = Path(src), Path(dst)
    with open(src, "rb") as f:
        if f.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise LogError(src, "not an MCAP file (bad magic bytes); nothing to repair")
    scan = McapScan(src)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    pending: dict[int, Channel] = {}
    n_msg = 0
    with open(dst, "wb") as out:
        w = Writer(out, compression=CompressionType.ZSTD)
        w.start(profile="", library="js2-repair")
        for rec in scan.records():
            if isinstance(rec, Schema):
                if rec.id not in schema_ids:
                    schema_ids[rec.id] = w.register_schema(rec.name, rec.encoding, rec.data)
            elif isinstance(rec, Channel):
                if rec.id not in channel_ids:
                    pending[rec.id] = rec
            elif isinstance(rec, Message):
                cid = channel_ids.get(rec.channel_id)
                if cid is None:
                    ch = pending.pop(rec.channel_id, None)
                    if ch is None:        # its channel record was in a lost chunk: nothing names the topic
                        continue
                    cid = channel_ids[ch.id] = w.register_channel(
                        ch.topic, ch.message_encoding, schema_ids.get(ch.schema_id, 0), dict(ch.metadata))
                w.add_message(cid, rec.log_time, rec.data, rec.publish_time, rec.sequence)
                n_msg += 1
            elif isinstance(rec, Metadata):
                w.add_metadata(rec.name, dict(rec.metadata))
            elif isinstance(rec, Attachment):
                w.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type, bytes(rec.data))
        w.add_metadata("js2_repair", {
            "source": str(src), "repaired": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "damage": scan.note() or "none: the file was intact", "messages": str(n_msg)})
        w.finish()
    return scan


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="js2-repair", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n", 2)[2])
    p.add_argument("log", help="the damaged .mcap")
    p.add_argument("-o", "--output", help="where to write the complete log (default: LOG.repaired.mcap beside it)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    src = Path(args.log)
    dst = Path(args.output) if args.output else src.with_name(src.stem + ".repaired.mcap")
    try:
        if src.is_dir():
            raise LogError(src, "is a folder, not a log file; give the .mcap file")
        if not src.is_file():
            raise LogError(src, "file not found")
        if dst.resolve() == src.resolve():
            raise Js2Error(f"-o {dst}: is the damaged log itself; write the repair to another file")
        if dst.exists() and not args.force:
            raise Js2Error(f"-o {dst}: the file exists; pass --force to overwrite it or choose another name")
        if not dst.parent.is_dir():
            raise Js2Error(f"-o {dst}: the folder {dst.parent} does not exist; create it first")
        try:
            scan = repair(src, dst)
        except OSError as e:
            raise Js2Error(f"cannot write {dst}: {e.strerror or e}; choose another -o") from None
    except Js2Error as e:
        print(f"js2-repair: error: {e}", file=sys.stderr)
        return 2
    what = scan.note() or "the file was intact (footer present); copied as is"
    print(f"js2-repair: {src} -> {dst}\n  {what}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

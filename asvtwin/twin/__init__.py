"""The twin: the runtime that joins every capability level, its clock, snapshots,
recording and replay."""

from __future__ import annotations

from asvtwin.twin.snapshot import SCHEMA_ID, Snapshot, decode, encode, json_schema

__all__ = ["SCHEMA_ID", "Snapshot", "decode", "encode", "json_schema"]

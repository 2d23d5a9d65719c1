"""AIS for the twin: NMEA decoding (pyais, and a numpy batch decoder for the one-sentence
position reports), validation, sources, targets with dead reckoning.

An AIS source is an async iterator of validated messages (:class:`AisReport`,
:class:`AisStatic`) in the scene's NED frame, all decoded by one :class:`AisPipeline`:

>>> from asvtwin.sources.ais import AisPipeline
>>> pipe = AisPipeline()
>>> batch = pipe.feed("\\\\s:2573555,c:1707873398*05\\\\!BSVDM,1,1,,A,13mB7d001E1dDH0`KlKBjB?<0490,0*34")
>>> len(batch), pipe.stats.errors["outside_scene"]  # a ship off Hammerfest, not in the fjord
(0, 1)
"""

from __future__ import annotations

from asvtwin.sources.ais.counters import ErrorCounter, ErrorKind, NoticeKind, PipelineStats
from asvtwin.sources.ais.fragments import FragmentAssembler
from asvtwin.sources.ais.network import Backoff, TcpAisSource, UdpAisSource
from asvtwin.sources.ais.pipeline import DYNAMIC_TYPES, STATIC_TYPES, AisPipeline, LogCensus
from asvtwin.sources.ais.registry import TargetRegistry, TargetSnapshot, nominal_report_interval_s
from asvtwin.sources.ais.replay import FileReplaySource, HistoryReplaySource, SyntheticAisSource
from asvtwin.sources.ais.reports import (
    CLASS_B_TYPES,
    AisMessage,
    AisReport,
    AisStatic,
    ReportBatch,
)
from asvtwin.sources.ais.source import AisSource, Pacer, PipelineSource, SourceStatus, tag_time
from asvtwin.sources.ais.spec import open_ais_source
from asvtwin.sources.ais.synthetic import (
    SyntheticLine,
    SyntheticTraffic,
    encode_report,
    encode_static,
    tag_block,
)
from asvtwin.sources.ais.tagblock import TagBlock, TagBlockError, parse_tag_block
from asvtwin.sources.ais.timebase import StreamClock
from asvtwin.sources.ais.traffic import FjordTraffic, TrafficVessel, default_fleet

__all__ = [
    "CLASS_B_TYPES",
    "DYNAMIC_TYPES",
    "STATIC_TYPES",
    "AisMessage",
    "AisPipeline",
    "AisReport",
    "AisSource",
    "AisStatic",
    "Backoff",
    "ErrorCounter",
    "ErrorKind",
    "FileReplaySource",
    "FjordTraffic",
    "FragmentAssembler",
    "HistoryReplaySource",
    "LogCensus",
    "NoticeKind",
    "Pacer",
    "PipelineSource",
    "PipelineStats",
    "ReportBatch",
    "SourceStatus",
    "StreamClock",
    "SyntheticAisSource",
    "SyntheticLine",
    "SyntheticTraffic",
    "TagBlock",
    "TagBlockError",
    "TargetRegistry",
    "TargetSnapshot",
    "TcpAisSource",
    "TrafficVessel",
    "UdpAisSource",
    "default_fleet",
    "encode_report",
    "encode_static",
    "nominal_report_interval_s",
    "open_ais_source",
    "parse_tag_block",
    "tag_block",
    "tag_time",
]

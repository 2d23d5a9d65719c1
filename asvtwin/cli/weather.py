"""``asvtwin weather show``: the weather the twin uses (synthetic fixture, a file, or MET Norway).

Offline by default: the bundled Trondheim fixture, a *synthetic* forecast authored for this
project in the Locationforecast 2.0 compact schema (labelled so in the output; not MET Norway
data). ``--file`` reads a compact-schema JSON file (e.g. a saved api.met.no response). ``--live``
asks api.met.no (it needs ``--user-agent`` naming you and a contact, or the environment
variable ``ASVTWIN_USER_AGENT``); nothing is contacted without it.
"""

from __future__ import annotations

import argparse
import math
from datetime import UTC
from typing import Any

from asvtwin.cli.argtypes import positive_float

__all__ = ["register"]


def register(subparsers: Any) -> None:
    """Add ``weather show`` to the ``asvtwin`` command."""
    weather = subparsers.add_parser("weather", help="weather forecast (MET Norway)",
                                    description=__doc__.split("\n\n")[0])
    sub = weather.add_subparsers(title="weather commands", metavar="COMMAND")
    weather.set_defaults(func=lambda args: (weather.print_help(), 2)[1])
    s = sub.add_parser("show", help="print the forecast the twin would use",
                       description="Print the weather series (the synthetic offline fixture by "
                       "default, labelled as such).")
    s.add_argument("--file", default=None, help="a compact-schema JSON file instead of the fixture")
    s.add_argument("--live", action="store_true",
                   help="fetch from api.met.no (needs --user-agent or ASVTWIN_USER_AGENT)")
    s.add_argument("--lat", type=float, default=63.43, help="latitude for --live [deg]")
    s.add_argument("--lon", type=float, default=10.39, help="longitude for --live [deg]")
    s.add_argument("--user-agent", default=None,
                   help="application and contact, e.g. 'asvtwin/0.1 you@example.com'")
    s.add_argument("--hours", type=positive_float, default=24.0,
                   help="hours of forecast to show")
    s.add_argument("--step", type=positive_float, default=3.0,
                   help="hours between rows (interpolated), > 0")
    s.add_argument("--json", action="store_true", help="print JSON rows")
    s.set_defaults(func=_show)


def _show(args: argparse.Namespace) -> int:
    import json
    import os
    import time
    from datetime import datetime

    import numpy as np
    from rich.console import Console
    from rich.table import Table

    from asvtwin.sources.weather import ATTRIBUTION, MetNoClient, OfflineWeatherSource

    console = Console()
    # errors (a bad --file, no User-Agent) end in one line on stderr, exit 2: asvtwin.cli.main
    if args.live:
        ua = args.user_agent or os.environ.get("ASVTWIN_USER_AGENT", "")
        source: Any = MetNoClient(args.lat, args.lon, user_agent=ua, clock=time.time)
    else:
        source = OfflineWeatherSource(args.file)
    fc = source.fetch()
    series = fc.series
    t0 = series.span_unix_s[0]
    times = np.arange(t0, min(t0 + args.hours * 3600.0, series.span_unix_s[1]) + 1.0,
                      args.step * 3600.0)
    v = series.interpolate(times)

    def fmt(x: float, f: str) -> str:
        return "-" if math.isnan(x) else format(x, f)

    rows = []
    for i, t in enumerate(times.tolist()):
        rows.append({
            "time": datetime.fromtimestamp(t, tz=UTC).strftime("%Y-%m-%dT%H:%MZ"),
            "wind_speed_m_s": v["wind_speed_m_s"][i],
            "wind_from_deg": math.degrees(v["wind_from_rad"][i]),
            "air_temperature_c": v["air_temperature_c"][i],
            "air_pressure_hpa": v["air_pressure_pa"][i] / 100.0,
            "relative_humidity_pct": 100.0 * v["relative_humidity"][i],
            "cloud_pct": 100.0 * v["cloud_fraction"][i],
        })
    if args.json:
        for r in rows:
            print(json.dumps({k: (None if isinstance(x, float) and math.isnan(x) else x)
                              for k, x in r.items()} | {"source": fc.source,
                                                        "synthetic": fc.synthetic}))
        return 0
    kind = "SYNTHETIC " if fc.synthetic else ""
    table = Table(title=f"{kind}Weather at {series.lat_deg:.2f} N {series.lon_deg:.2f} E "
                  f"({fc.source}{', STALE' if fc.stale else ''})", title_justify="left")
    for col in ("time (UTC)", "wind m/s", "from deg", "temp C", "pressure hPa", "RH %",
                "cloud %"):
        table.add_column(col, justify="right")
    for r in rows:
        table.add_row(r["time"], fmt(r["wind_speed_m_s"], ".1f"), fmt(r["wind_from_deg"], ".0f"),
                      fmt(r["air_temperature_c"], ".1f"), fmt(r["air_pressure_hpa"], ".1f"),
                      fmt(r["relative_humidity_pct"], ".0f"), fmt(r["cloud_pct"], ".0f"))
    console.print(table)
    upd = datetime.fromtimestamp(series.updated_unix_s, tz=UTC)
    credit = ("Synthetic data authored for asvtwin: not a forecast, not MET Norway data."
              if fc.synthetic else ATTRIBUTION if fc.source == "met.no"
              else f"From {fc.source}.")
    console.print(f"{len(series)} steps, updated {upd:%Y-%m-%d %H:%MZ}. {credit}")
    return 0

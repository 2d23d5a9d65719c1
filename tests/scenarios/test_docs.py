"""docs/scenarios.md stays true to the schema: the annotated example validates, every field
of every model is documented, and the library table lists every shipped scenario."""

from __future__ import annotations

import re
from pathlib import Path

from asvtwin.scenarios import library_names, parse_scenario, schema

DOC = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"


def test_annotated_example_is_a_valid_scenario():
    text = DOC.read_text()
    block = re.search(r"```yaml\n(.*?)```", text, re.DOTALL)
    assert block is not None
    s = parse_scenario(block.group(1), "docs/scenarios.md")
    assert s.name == "crossing_give_way"


def test_every_field_is_documented():
    text = DOC.read_text()
    models = [schema.Scenario, schema.OwnShipSpec, schema.TargetSpec, schema.AisSpec,
              schema.WeatherSpec, schema.EnvironmentSpec, schema.SensorSpec, schema.RatesSpec,
              schema.CriteriaSpec, schema.Waypoints, schema.AisReplay, schema.Colreg]
    missing = [f"{m.__name__}.{f}" for m in models for f in m.model_fields
               if f != "kind" and f"`{f}`" not in text]
    assert not missing, f"fields without documentation in docs/scenarios.md: {missing}"


def test_library_table_lists_every_scenario():
    text = DOC.read_text()
    assert all(f"| `{n}` |" in text for n in library_names())

"""The scenario key reference (docs/scenario_keys.md) is generated from the pydantic models and kept fresh: the
committed file equals a fresh generation, and every key has a description (with its unit where its name says it
has one)."""

from __future__ import annotations

import re

from renderlab.scenario import keyref

#: key-name endings that are a unit: such a key's description must end with its unit in brackets
UNIT_SUFFIXES = ("_m", "_km", "_deg", "_s", "_px", "_mps", "_m2", "_hz", "_h", "_arcsec", "_mrad", "_frac",
                 "_w_m2", "_deg_s", "_kg_m2", "_per_m2", "_m2_s3", "_m2_kg", "_cells")


def test_committed_reference_is_fresh():
    fresh = keyref.render()
    committed = keyref.DOC.read_text(encoding="utf-8") if keyref.DOC.is_file() else ""
    assert committed == fresh, (f"{keyref.DOC} is stale (the scenario models changed); regenerate it with "
                                f"`{keyref.REGENERATE}` and commit it")


def test_every_field_has_a_description():
    missing = [key for key, _, _, f in keyref.iter_fields() if not (f.description or "").strip()]
    assert missing == []


def test_unit_named_keys_state_their_unit():
    """A key whose name carries a unit (``range_m``) ends its description with it in brackets (``[m]``)."""
    bad = [key for key, _, name, f in keyref.iter_fields()
           if name.endswith(UNIT_SUFFIXES) and not keyref.split_unit(f.description or "")[1]]
    assert bad == []


def test_reference_covers_every_key_and_kind():
    text = keyref.render()
    keys = set(re.findall(r"^\| `([^`]+)` \|", text, re.M))
    assert {k for k, *_ in keyref.iter_fields()} <= keys
    for title in ("`[world]` — kind `ev5`", "`[trajectory]` — kind `leo`", "`[[world.bodies]]`", "`[coastline]`",
                  "`[world.site]` (world kind `ev5`)"):
        assert f"## {title}" in text
    assert "`camera.fov_deg`" in text and "`sensor.exposure_s`" in text  # loader keys and SensorOptions
    row = next(line for line in text.splitlines() if line.startswith("| `camera.width` |"))
    assert row == "| `camera.width` | integer | `256` | (0, 16384] | px | Image width |"


def test_check_mode_reports_staleness(tmp_path, capsys):
    stale = tmp_path / "keys.md"
    stale.write_text("old\n", encoding="utf-8")
    assert keyref.main(["--check", "--out", str(stale)]) == 1
    assert keyref.REGENERATE in capsys.readouterr().out
    assert keyref.main(["--out", str(stale)]) == 0 and keyref.main(["--check", "--out", str(stale)]) == 0

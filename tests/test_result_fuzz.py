"""Fuzz of the result-file paths (issue 28): a result with any one field replaced by any
JSON value (hostile strings, NaN and huge numbers, wrong shapes, nesting) is exported to
every format, or refused with a one-line error naming the file; never an internal error,
a traceback or a file written beside a refusal."""

from __future__ import annotations

import contextlib
import io
import json
import math
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lightcal.cli.main import main

FORMATS = {"opencv": ".yaml", "blender": ".py", "mitsuba": ".xml", "ies": ".ies"}

HOSTILE = ['"""', "'''", "</x><!--", "\x00", "\n---\n", "${HOME}", "\u202e", "%s%n", "a" * 5000]

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -0.0])
    | st.text(max_size=40)
    | st.sampled_from(HOSTILE),
    lambda inner: (
        st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=12,
)


def _leaf_paths(node: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path to a value in the document (containers included)."""
    out = [path] if path else []
    if isinstance(node, dict):
        for key, value in node.items():
            out += _leaf_paths(value, (*path, key))
    elif isinstance(node, list):
        for k, value in enumerate(node[:4]):
            out += _leaf_paths(value, (*path, k))
    return out


@pytest.fixture(scope="module")
def result_doc(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    out = tmp_path_factory.mktemp("fuzz_result") / "result.json"
    argv = ["calibrate", str(tiny_dataset / "project.json"), "--out", str(out), "--quiet"]
    assert main(argv) in (0, 3)
    data = json.loads(out.read_text())
    light = data["lights"][0]
    if light.get("rid") is None:  # a RID to export as IES: a cos^m profile
        light["rid"] = {"type": "cos_power", "m": 3.0}
    return data


def _export(path: Path, fmt: str, out: Path) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(["export", str(path), "--format", fmt, "--out", str(out)])
    return code, err.getvalue()


@settings(
    max_examples=200,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(data=st.data())
def test_any_broken_field_is_exported_or_refused_in_one_line(
    result_doc: dict[str, Any], tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    doc = json.loads(json.dumps(result_doc))
    paths = _leaf_paths(doc)
    where = data.draw(st.sampled_from(paths), label="field")
    value = data.draw(json_values, label="value")
    node: Any = doc
    for key in where[:-1]:
        node = node[key]
    node[where[-1]] = value
    folder = tmp_path_factory.mktemp("fuzz")
    path = folder / "result.json"
    path.write_text(json.dumps(doc, allow_nan=True))
    fmt = data.draw(st.sampled_from(sorted(FORMATS)), label="format")
    out = folder / f"export{FORMATS[fmt]}"
    code, err = _export(path, fmt, out)
    assert "internal error" not in err and "Traceback" not in err, (where, value, err)
    if code == 0:
        assert out.is_file()
    else:
        assert code == 2, (where, value, err)
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("lightcal export: error: "), err
        assert not out.exists()

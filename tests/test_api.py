"""The Python API: docs/api.md's example runs as written, `import lightcal` stays cheap,
and the first call says when it compiles the kernels."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

import lightcal

REPO = Path(__file__).resolve().parents[1]


def _python_blocks(markdown: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", markdown, flags=re.S | re.M)


def test_docs_example_runs(tmp_path):
    (block,) = _python_blocks((REPO / "docs/api.md").read_text())
    script = tmp_path / "example.py"
    script.write_text(block)
    run = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=900
    )
    assert run.returncode == 0, run.stderr[-3000:]
    out = run.stdout
    assert re.search(r"iteration \d+: cost", out)
    assert "light: position [" in out and "12 renders of 1200 x 800 px" in out
    assert "scene.xml, scene_rid_0.png, light.yaml, lights.launch.xml, lights.urdf" in out
    assert re.search(r"^1\. ", out, flags=re.M) and re.search(r"^2\. ", out, flags=re.M)
    folder = tmp_path / "api-example"
    for name in ("result.json", "scene.xml", "light.yaml", "lights.urdf"):
        assert (folder / name).is_file()


def test_import_lightcal_imports_nothing_heavy():
    code = (
        "import sys, lightcal; "
        "print(sorted(m for m in sys.modules if m.startswith('lightcal') or m in "
        "('numpy', 'scipy', 'numba', 'cv2', 'pydantic')))"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "['lightcal']"


def test_the_api_names_are_attributes():
    for name in lightcal.API:
        assert getattr(lightcal, name) is getattr(__import__("lightcal.api").api, name)
    assert set(lightcal.API) <= set(dir(lightcal))
    with pytest.raises(AttributeError, match="no attribute 'nosuch'"):
        lightcal.nosuch  # noqa: B018


def test_the_first_call_says_it_compiles(monkeypatch):
    import lightcal.warmup as warmup

    calls: list[str] = []
    monkeypatch.setattr(warmup, "kernels_ready", lambda: False)
    monkeypatch.setattr(warmup, "warm_up", lambda *a, **k: 12.0)
    assert lightcal.ensure_compiled(calls.append) == 12.0
    assert calls[0] == lightcal.COMPILE_MESSAGE and "compiling the numba kernels" in calls[0]
    assert calls[1] == "lightcal: kernels compiled in 12 s (cached from now on)"


def test_compiled_kernels_say_nothing(monkeypatch, capsys):
    import lightcal.warmup as warmup

    monkeypatch.setattr(warmup, "kernels_ready", lambda: True)
    assert lightcal.ensure_compiled() == 0.0
    assert capsys.readouterr().err == ""


def test_default_notice_goes_to_stderr(monkeypatch, capsys):
    import lightcal.warmup as warmup

    monkeypatch.setattr(warmup, "kernels_ready", lambda: False)
    monkeypatch.setattr(warmup, "warm_up", lambda *a, **k: 1.0)
    lightcal.ensure_compiled()
    err = capsys.readouterr().err
    assert err.splitlines()[0] == lightcal.COMPILE_MESSAGE


def test_calibrate_refuses_a_missing_project(tmp_path):
    from lightcal.errors import InputError

    with pytest.raises(InputError, match=r"missing\.json"):
        lightcal.calibrate(tmp_path / "missing.json", notify=None)

"""`lightcal calibrate` says what bends the rays before it solves: a line per flat port
(`lightcal.pipeline.port_text.port_lines`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lightcal.cli.main import main
from lightcal.core.flat_port import FlatPort
from lightcal.core.rid import CosPowerRID
from lightcal.core.scene import Light
from lightcal.pipeline.port_text import port_lines


def test_port_lines_name_the_camera_then_each_ported_light() -> None:
    rid = CosPowerRID(3.0)
    bare = Light(rid, np.zeros(3), name="bare")
    ported = Light(rid, np.zeros(3), name="led", port=FlatPort(0.015, 0.008))
    camera = FlatPort(0.02, 0.01, 1.49, 1.333)
    assert port_lines(None, [bare]) == []
    lines = port_lines(camera, [bare, ported])
    assert lines[0] == (
        "camera behind a flat port: 20 mm to the glass, 10 mm acrylic (n 1.49) into water (n 1.333)"
    )
    assert len(lines) == 2 and lines[1].startswith(
        "led behind a flat port: 15 mm to the glass, 8 mm acrylic (n 1.49) into water "
        "(n 1.333); its beam in the water: half intensity at "
    )


def test_calibrate_prints_the_lights_port(tmp_path: Path, capsys) -> None:
    out = tmp_path / "data"
    argv = ["synth", str(out), "--width", "80", "--height", "60", "--views", "4", "--quiet"]
    assert main([*argv, "--light-port", "15", "8", "1.49", "1.333", "--declare-light-port"]) == 0
    capsys.readouterr()
    code = main(["calibrate", str(out / "project.json"), "--out", str(tmp_path / "r.json")])
    captured = capsys.readouterr()  # progress and set-up on stderr, the summary on stdout
    printed = captured.err
    assert code in (0, 3), captured.out
    assert "light behind a flat port: 15 mm to the glass, 8 mm acrylic (n 1.49)" in printed

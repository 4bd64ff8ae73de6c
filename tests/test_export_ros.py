"""`lightcal export --format ros`: the static transforms and URDF joints, parsed and
recomposed with SciPy (scalar-last quaternions, fixed-axis Euler angles): the rotation
and position of every light's `T_camera_light` to 1e-12."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from lightcal.cli.main import main
from lightcal.core.pose import describe_pose
from lightcal.io.export_ros import PARENT_FRAME, frame_name, rpy_from_matrix
from lightcal.io.project import load_project
from lightcal.io.result_file import read_result, write_result
from tests.export_render import result_of_project


@pytest.fixture(scope="module")
def result_path(tmp_path_factory) -> Path:
    """Three lights of random orientations, one with a name that is no ROS frame name."""
    folder = tmp_path_factory.mktemp("ros")
    assert main(["synth", str(folder / "d"), "--views", "2", "--lights", "3", "--quiet"]) == 0
    path = result_of_project(load_project(folder / "d/project.json"), [1.0] * 3, folder / "r.json")
    result = read_result(path)
    rng = np.random.default_rng(3)
    lights = []
    for k, light in enumerate(result.lights):
        R = Rotation.random(random_state=rng).as_matrix()
        pose = describe_pose(R, rng.normal(0, 0.1, 3))
        name = ["key light", "2nd/fill", "key_light"][k]
        lights.append(light.model_copy(update={**pose, "name": name, "pose_kind": "general"}))
    write_result(result.model_copy(update={"lights": lights}), path)
    return path


def _export(result_path: Path, out: Path) -> tuple[ET.Element, ET.Element, str]:
    assert main(["export", str(result_path), "--format", "ros", "--out", str(out)]) == 0
    urdf = out.with_name("lights.urdf")
    text = out.read_text()
    return ET.fromstring(text), ET.parse(urdf).getroot(), text


def _args(node: ET.Element) -> dict[str, str]:
    words = node.get("args", "").split()
    return {words[i][2:]: words[i + 1] for i in range(0, len(words), 2)}


def test_launch_file_recomposes_each_pose(result_path, tmp_path):
    result = read_result(result_path)
    launch, _, text = _export(result_path, tmp_path / "lights.launch.xml")
    assert launch.tag == "launch"
    assert "x y z w" in text and "REP-103" in text and "optical" in text
    nodes = launch.findall("node")
    assert [n.get("exec") for n in nodes] == ["static_transform_publisher"] * 3
    children = []
    for node, light in zip(nodes, result.lights, strict=True):
        args = _args(node)
        assert args["frame-id"] == PARENT_FRAME
        children.append(args["child-frame-id"])
        q = [float(args[k]) for k in ("qx", "qy", "qz", "qw")]
        R = Rotation.from_quat(q).as_matrix()  # SciPy: scalar last, as ROS
        np.testing.assert_allclose(R, light.R_camera_light, atol=1e-12)
        xyz = [float(args[k]) for k in ("x", "y", "z")]
        np.testing.assert_allclose(xyz, light.position_m, atol=0)
    assert children == ["key_light", "light_2nd_fill", "key_light_"]  # safe and unique
    # the ROS 1 command lines in the comment say the same numbers
    ros1 = re.findall(r"static_transform_publisher ([-0-9.e ]+)\n\s+([-0-9.e ]+) (\S+) (\S+)", text)
    assert len(ros1) == 3
    for (xyz, q, parent, child), light, name in zip(ros1, result.lights, children, strict=True):
        assert (parent, child) == (PARENT_FRAME, name)
        R = Rotation.from_quat([float(v) for v in q.split()]).as_matrix()
        np.testing.assert_allclose(R, light.R_camera_light, atol=1e-12)
        np.testing.assert_allclose([float(v) for v in xyz.split()], light.position_m, atol=0)


def test_urdf_joints_recompose_each_pose(result_path, tmp_path):
    result = read_result(result_path)
    _, robot, _ = _export(result_path, tmp_path / "lights.launch.xml")
    joints = robot.findall("joint")
    assert len(joints) == 3
    links = {link.get("name") for link in robot.findall("link")}
    for joint, light in zip(joints, result.lights, strict=True):
        assert joint.get("type") == "fixed"
        parent, child = joint.find("parent"), joint.find("child")
        assert parent is not None and child is not None
        assert parent.get("link") == PARENT_FRAME and child.get("link") in links
        origin = joint.find("origin")
        assert origin is not None
        rpy = [float(v) for v in origin.get("rpy", "").split()]
        R = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x, y, z: Rz Ry Rx
        np.testing.assert_allclose(R, light.R_camera_light, atol=1e-12)
        xyz = [float(v) for v in origin.get("xyz", "").split()]
        np.testing.assert_allclose(xyz, light.position_m, atol=0)


@pytest.mark.parametrize("pitch", [math.pi / 2, -math.pi / 2])
def test_rpy_at_gimbal_lock(pitch):
    R = Rotation.from_euler("xyz", [0.3, pitch, -0.7]).as_matrix()
    back = Rotation.from_euler("xyz", rpy_from_matrix(R)).as_matrix()
    np.testing.assert_allclose(back, R, atol=1e-9)


def test_frame_names():
    assert frame_name("light") == "light"
    assert frame_name("") == "light"
    assert frame_name('<a href="x">') == "_a_href__x__"
    assert frame_name("9") == "light_9"


def test_ros_export_of_a_result_needs_an_xml_name(result_path, tmp_path, capsys):
    assert main(["export", str(result_path), "--format", "ros", "--out", str(tmp_path / "a.py")])
    assert "expected a .xml file" in capsys.readouterr().err

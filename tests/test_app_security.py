"""The app's guards (issue 10, App): origin and token, confinement of uploads, upload
limits, bytes in flight, image headers, the upload folder's bound, autosave failures,
SIGTERM and leftover temporary files.

Each app is built on port 0 on the small synthetic project of `tests/app_fixtures.py`;
websocket and HTTP clients talk to it as another web page or a script would.
"""

from __future__ import annotations

import http.client
import io
import json
import os
import signal
import struct
import subprocess
import sys
import time
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import viser
import websockets.exceptions
import websockets.sync.client
from lightcal_app.server import LightcalApp, build_app
from lightcal_app.upload_checks import check_image_headers, make_room, unpack_zip
from viser import _messages
from viser._gui_handles import GuiEvent, UploadedFile
from viser.infra import ClientId

from lightcal.errors import InputError
from tests.app_fixtures import SyntheticProject, make_project

SUBPROTOCOL = f"viser-v{viser.__version__}"


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> SyntheticProject:
    return make_project(tmp_path_factory.mktemp("sec"), n_views=3, width=64, height=48)


def _build(project: SyntheticProject, tmp: Path, **kw: Any) -> LightcalApp:
    kw.setdefault("session_path", tmp / "autosave.session.json")
    a = build_app(project.path, port=0, state_dir=tmp / "state", **kw)
    assert a.wait_idle()
    return a


@pytest.fixture
def app(synthetic: SyntheticProject, tmp_path: Path):
    a = _build(synthetic, tmp_path)
    yield a
    a.close()


def _upload(handle: Any, name: str, content: bytes) -> None:
    """What viser does when a browser's upload completes (client None)."""
    handle._impl.value = UploadedFile(name, content)
    for cb in handle._impl.update_cb:
        cb(GuiEvent(client=None, client_id=None, target=handle))


def _ws(port: int, **kw: Any) -> Any:
    return websockets.sync.client.connect(
        f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=5, proxy=None, **kw
    )


def _status(exc: pytest.ExceptionInfo) -> int:
    return int(exc.value.response.status_code)


def _http(port: int, path: str, headers: dict[str, str] | None = None) -> http.client.HTTPResponse:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
    conn.request("GET", path, headers=headers or {})
    return conn.getresponse()


# ---------------------------------------------------------------------------- origin, token


def test_a_page_from_another_origin_cannot_open_the_websocket(app: LightcalApp) -> None:
    port = app.server.get_port()
    with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
        _ws(port, origin="http://evil.example")
    assert _status(exc) == 403
    with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
        _ws(port, origin=f"http://localhost:{port + 1}")  # another port: another origin
    assert _status(exc) == 403
    # The page's own origin, and a script that sends none, connect.
    with _ws(port, origin=f"http://127.0.0.1:{port}") as ws:
        assert ws.recv(timeout=5)
    with _ws(port) as ws:
        assert ws.recv(timeout=5)
    # A DNS-rebinding page (its own name resolved to 127.0.0.1) is refused too.
    r = _http(port, "/", {"Host": f"evil.example:{port}"})
    assert r.status == 403 and b"localhost" in r.read()
    assert _http(port, "/").status == 200


def test_off_loopback_every_request_needs_the_token(
    synthetic: SyntheticProject, tmp_path: Path
) -> None:
    a = _build(synthetic, tmp_path, host="0.0.0.0")
    try:
        token = a.access.token
        assert token is not None and len(token) >= 32
        port = a.server.get_port()
        assert a.url == f"http://127.0.0.1:{port}/?token={token}"
        assert _http(port, "/").status == 403
        assert _http(port, "/?token=wrong").status == 403
        r = _http(port, f"/?token={token}")
        assert r.status == 200
        cookie = r.getheader("Set-Cookie") or ""
        assert cookie.startswith(f"lightcal_token={token};") and "HttpOnly" in cookie
        # The page's own requests carry the cookie.
        assert _http(port, "/", {"Cookie": f"lightcal_token={token}"}).status == 200
        with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
            _ws(port)
        assert _status(exc) == 403
        with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
            _ws(port, additional_headers={"Cookie": "lightcal_token=nope"})
        assert _status(exc) == 403
        with _ws(port, additional_headers={"Cookie": f"lightcal_token={token}"}) as ws:
            assert ws.recv(timeout=5)
        with pytest.raises(websockets.exceptions.InvalidStatus):  # the origin still counts
            _ws(
                port,
                origin="http://evil.example",
                additional_headers={"Cookie": f"lightcal_token={token}"},
            )
    finally:
        a.close()


def test_loopback_needs_no_token(app: LightcalApp) -> None:
    assert app.access.token is None and "token" not in app.url


# ---------------------------------------------------------------------------- uploads


def _project_zip(synthetic: SyntheticProject, edit: Any = None) -> bytes:
    folder = synthetic.path.parent
    doc = json.loads(synthetic.path.read_text())
    if edit is not None:
        edit(doc)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for p in sorted(folder.rglob("*")):
            if p.is_file() and p.suffix in (".yaml", ".png"):
                zf.write(p, f"p/{p.relative_to(folder)}")
        zf.writestr("p/project.json", json.dumps(doc))
    return buf.getvalue()


def _uploads_left(a: LightcalApp) -> list[Path]:
    root = a.controller.files.upload_root
    return sorted(root.iterdir()) if root.is_dir() else []


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("images[1].path", "ABSOLUTE"),
        ("images[1].path", "../../secret.png"),
        ("camera.path", "ABSOLUTE"),
        ("images[0].mask", "images/../../x/secret.png"),
        ("images[0].dark", "ABSOLUTE"),
        ("images[1].dark", "../secret.png"),
    ],
)
def test_uploaded_projects_stay_in_their_folder(
    app: LightcalApp, synthetic: SyntheticProject, tmp_path: Path, field: str, value: str
) -> None:
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"SECRET-LINE-1\nSECRET-LINE-2\n")
    value = str(secret) if value == "ABSOLUTE" else value

    def edit(doc: dict) -> None:
        if field.startswith("images"):
            i, key = int(field[7]), field.split(".")[1]
            doc["images"][i][key] = value
        else:
            doc["camera"]["path"] = value

    before = secret.stat().st_atime_ns
    _upload(app.panels.files.upload_project, "evil.zip", _project_zip(synthetic, edit))
    title, body = app.state.messages[-1]
    assert title == "⚠ Upload rejected: evil.zip"
    assert body == (
        f"evil.zip: {field}: expected a path inside the uploaded project (relative, without "
        "'..'); absolute and escaping paths are refused"
    )
    assert "SECRET" not in body and str(tmp_path) not in body
    assert secret.stat().st_atime_ns == before  # never opened
    assert _uploads_left(app) == []  # the rejected upload's folder is gone
    assert app.state.project.path == synthetic.path.resolve()


def test_a_good_project_upload_is_kept(app: LightcalApp, synthetic: SyntheticProject) -> None:
    _upload(app.panels.files.upload_project, "good.zip", _project_zip(synthetic))
    assert app.wait_idle()
    assert app.state.messages[-1][0] == "Project updated"
    assert len(_uploads_left(app)) == 1


def test_zip_limits_are_checked_before_and_while_unpacking(tmp_path: Path) -> None:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("project.json", "{}")
        zf.writestr("big.bin", b"\0" * 100_000)  # 100 kB unpacked, ~100 bytes packed
    content = buf.getvalue()
    assert len(content) < 2000
    with pytest.raises(InputError, match=r"unpacks to more than 50\.0 kB"):
        unpack_zip("bomb.zip", content, tmp_path / "a", max_bytes=50_000)
    with pytest.raises(InputError, match="the zip holds 2 files; at most 1"):
        unpack_zip("many.zip", content, tmp_path / "b", max_members=1)
    assert not (tmp_path / "b").exists()  # refused before anything was written
    # A zip whose directory lies about the sizes is stopped by the bytes written.
    lying = bytearray(content)
    for sig in (b"PK\x01\x02", b"PK\x03\x04"):  # central directory and local headers
        at = lying.find(sig, lying.find(b"big.bin") - 60)
        while at >= 0:
            off = 24 if sig == b"PK\x01\x02" else 22
            struct.pack_into("<I", lying, at + off, 10)  # uncompressed size: 10 bytes
            at = lying.find(sig, at + 4)
    with pytest.raises(InputError):
        unpack_zip("liar.zip", bytes(lying), tmp_path / "c", max_bytes=50_000)


def test_a_zip_without_a_project_is_refused_unpacked(app: LightcalApp) -> None:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("junk.bin", b"\0" * 1_000_000)
    _upload(app.panels.files.upload_project, "junk.zip", buf.getvalue())
    assert app.state.messages[-1][1] == (
        "junk.zip: no project file in the upload; expected project.json (or .yaml)"
    )
    assert _uploads_left(app) == []


def _png_header(width: int, height: int) -> bytes:
    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (
        b"\x89PNG\r\n\x1a\n"
        + struct.pack(">I", len(ihdr))
        + chunk
        + struct.pack(">I", zlib.crc32(chunk))
    )


def test_image_sizes_are_read_from_the_header_before_decoding(
    app: LightcalApp, tmp_path: Path
) -> None:
    huge = tmp_path / "huge.png"
    huge.write_bytes(_png_header(100_000, 100_000))
    with pytest.raises(InputError, match=r"huge.png: the image is 100000 x 100000 pixels"):
        check_image_headers([huge], "up.png")
    npy = tmp_path / "wide.npy"
    with npy.open("wb") as f:
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f4", "fortran_order": False, "shape": (10, 30_000)}
        )
    with pytest.raises(InputError, match=r"the image is 30000 x 10 pixels"):
        check_image_headers([npy], "up.npy")
    name = app.state.project.image_paths[0].name
    _upload(app.panels.files.upload_image, name, _png_header(100_000, 100_000))
    assert "the image is 100000 x 100000 pixels" in app.state.messages[-1][1]
    assert _uploads_left(app) == []


def test_the_upload_folder_is_bounded_oldest_first(tmp_path: Path) -> None:
    root = tmp_path / "uploads"
    for k, name in enumerate(("old", "mid", "new")):
        (root / name).mkdir(parents=True)
        (root / name / "f.bin").write_bytes(b"x" * 1000)
        os.utime(root / name, (1000 + k, 1000 + k))
    make_room(root, 500, keep=[root / "old"], limit=3000)
    assert sorted(p.name for p in root.iterdir()) == ["new", "old"]  # "old" is in use
    make_room(root, 1000, limit=3000)
    assert sorted(p.name for p in root.iterdir()) == ["new", "old"]  # it fits
    make_room(root, 2000, limit=3000)
    assert sorted(p.name for p in root.iterdir()) == ["new"]


def _transfer(a: LightcalApp, message: Any) -> None:
    for handler in list(a.server._websock_server._incoming_handlers[type(message)]):
        handler(ClientId(0), message)


def _start(a: LightcalApp, transfer: str, size: int, parts: int = 4) -> None:
    _transfer(
        a,
        _messages.FileTransferStartUpload(
            source_component_uuid=a.panels.files.upload_project._impl.uuid,
            transfer_uuid=transfer,
            filename=f"{transfer}.zip",
            mime_type="application/zip",
            part_count=parts,
            size_bytes=size,
        ),
    )


def _part(a: LightcalApp, transfer: str, index: int, n: int) -> None:
    _transfer(
        a,
        _messages.FileTransferPart(
            source_component_uuid=a.panels.files.upload_project._impl.uuid,
            transfer_uuid=transfer,
            part_index=index,
            content=b"x" * n,
        ),
    )


def test_upload_bytes_in_flight_are_bounded(synthetic: SyntheticProject, tmp_path: Path) -> None:
    a = _build(synthetic, tmp_path, upload_limit_bytes=1000)
    try:
        states = a.server.gui._current_file_upload_states
        # Announced 100 bytes, sends more: dropped before the extra bytes are kept.
        _start(a, "liar", 100)
        _part(a, "liar", 0, 80)
        assert states["liar"]["transferred_bytes"] == 80
        _part(a, "liar", 1, 80)
        assert "liar" not in states
        assert a.state.messages[-1] == (
            "⚠ Upload rejected: liar.zip",
            "liar.zip: more bytes arrived than the upload announced",
        )
        # Per browser: 2 x the per-file limit in flight at most (here 2000 bytes).
        for t in ("t1", "t2", "t3"):
            _start(a, t, 900)
        for t in ("t1", "t2"):
            _part(a, t, 0, 800)
        _part(a, "t3", 0, 800)
        assert "t3" not in states and {"t1", "t2"} <= states.keys()
        assert "too many uploads at once" in a.state.messages[-1][1]
        # Announced too large: dropped when it starts.
        _start(a, "huge", 5000)
        assert "huge" not in states
        assert a.state.messages[-1][1] == (
            "huge.zip: the file is 5.0 kB; uploads are limited to 1.0 kB per file"
        )
    finally:
        a.close()


# ---------------------------------------------------------------------------- sessions


def test_killed_saves_leave_no_temporary_files(synthetic: SyntheticProject, tmp_path: Path) -> None:
    stale = tmp_path / ".autosave.session.json.0123456789ab.tmp"
    stale.write_text("half a session")
    other = tmp_path / "unrelated.tmp"
    other.write_text("not ours")
    a = _build(synthetic, tmp_path)
    a.close()
    assert not stale.exists() and other.exists()


def test_a_failing_autosave_says_so_once_and_keeps_the_last_file(
    synthetic: SyntheticProject, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import lightcal_app.files_service as files_service

    a = _build(synthetic, tmp_path)
    try:
        path = tmp_path / "autosave.session.json"
        deadline = time.monotonic() + 30  # the first autosave, after the first redraw
        while not path.is_file() and time.monotonic() < deadline:
            time.sleep(0.05)
        good = path.read_bytes()

        def broken(session: Any, target: Path) -> None:
            raise OSError(28, "No space left on device", str(target))

        monkeypatch.setattr(files_service, "write_session", broken)
        for k in range(3):
            a.controller.set_show_selection(k % 2 == 0)
            assert a.wait_idle()
            time.sleep(0.6)  # past the autosave interval
            assert a.wait_idle()
        failures = [m for m in a.state.messages if m[0] == "⚠ Autosave failed"]
        assert len(failures) == 1
        assert str(tmp_path) not in failures[0][1]
        assert path.read_bytes() == good
    finally:
        a.controller.files.session_path = None
        a.close()


DRIVER = """
import sys
import lightcal_app.files_service as fs
from lightcal_app.server import build_app, serve_forever
fs.AUTOSAVE_INTERVAL_S = 1e9  # only the final autosave writes
app = build_app(sys.argv[1], port=0, session_path=__import__("pathlib").Path(sys.argv[2]),
                state_dir=__import__("pathlib").Path(sys.argv[3]))
assert app.wait_idle()
serve_forever(app, on_ready=lambda: print("ready", flush=True))
print("closed", flush=True)
"""


def test_sigterm_runs_the_final_autosave(synthetic: SyntheticProject, tmp_path: Path) -> None:
    session = tmp_path / "s.session.json"
    proc = subprocess.Popen(
        [sys.executable, "-c", DRIVER, str(synthetic.path), str(session), str(tmp_path / "st")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ},
    )
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "ready"
        assert not session.exists()
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "closed" in out and "Traceback" not in err
    assert json.loads(session.read_text())["format"] == "lightcal-app-session"
    assert not list(tmp_path.glob(".*.tmp"))


def test_an_edited_project_keeps_every_file_it_names(tmp_path: Path) -> None:
    """An upload that edits the project shown (an RID, an image) writes it elsewhere: every
    path the project names, light-off photos included, is made absolute against the
    project's folder, so the edited project reads the same files."""
    from lightcal_app.upload_checks import project_paths
    from lightcal_app.uploads import absolute_spec

    from lightcal.io.project_spec import ProjectFile
    from lightcal.resources import sample_project_dir

    data = json.loads((sample_project_dir() / "project.json").read_text(encoding="utf-8"))
    data["images"] = data["images"][:1]
    data["images"][0].update(mask="masks/a.png", dark="dark/a.png")
    data["sensor"].update(response="curve.json", model="map", vignetting="v.npy")
    spec = ProjectFile.model_validate(data)
    fixed = absolute_spec(spec, tmp_path)
    for field, path in project_paths(fixed):
        assert Path(path).is_absolute(), field
        assert Path(path).is_relative_to(tmp_path.resolve()), field
    assert {f for f, _ in project_paths(fixed)} == {
        "camera.path",
        "sensor.vignetting",
        "sensor.response",
        "images[0].path",
        "images[0].mask",
        "images[0].dark",
        "lights[0].rid.path",
    }

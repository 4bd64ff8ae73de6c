"""`lightcal app [PROJECT] [--host H] [--port P] [--demo] [--fresh]`: the calibration app.

Opens the interactive calibration page (viser) on the project, by default the bundled
sample project, and serves it until Ctrl-C. Installed, the sample is first copied to the
user's data folder (`lightcal.resources.user_sample_dir`), so that the autosave beside
the project and any edits never go into site-packages; in a source checkout the app
opens sample_data/ in place. It binds 127.0.0.1 (this machine only) unless `--host` says
otherwise; viser's share tunnel is never used.
"""

from __future__ import annotations

import argparse
import ipaddress
import re
import sys
from pathlib import Path

from lightcal.cli import collector
from lightcal.cli.arguments import path_arg
from lightcal.errors import InputError

EXPOSED_HOSTS = ("0.0.0.0", "::", "")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "app",
        help="open the interactive calibration app in the browser",
        description="Serve the interactive calibration page for a project.",
    )
    p.add_argument(
        "project",
        nargs="?",
        type=path_arg,
        help="project file (JSON or YAML); default: the bundled sample project "
        "(sample_data/ of a source checkout; installed: a copy in ~/.local/share/lightcal)",
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default 127.0.0.1, this machine only; 0.0.0.0 exposes "
        "the app to the network, behind a random access token printed in the URL)",
    )
    p.add_argument("--port", type=int, default=8080, help="TCP port (default 8080)")
    p.add_argument(
        "--demo",
        action="store_true",
        help="also show the true light from truth.json beside the project (synthetic data); "
        "starts from the project's guess every time and autosaves to "
        "<project>.demo-session.json",
    )
    p.add_argument(
        "--fresh",
        action="store_true",
        help="do not restore the autosaved session (it is kept aside under a timestamped name)",
    )
    p.add_argument(
        "--session",
        type=path_arg,
        help="autosave file (default: <project>.session.json beside the project)",
    )
    p.add_argument(
        "--state-dir",
        type=path_arg,
        help="folder for uploads and sessions of read-only projects "
        "(default: $XDG_STATE_HOME/lightcal)",
    )
    p.set_defaults(func=run)


def sample_project_missing(path: Path) -> InputError:
    """The error when `lightcal app` runs without a project and the sample is missing."""
    return InputError(
        path,
        "the sample project is missing; expected sample_data/project.json in the repository "
        "(regenerate it with `.venv/bin/python sample_data/make_sample_data.py`, see "
        "sample_data/README.md), or give a project file: lightcal app PROJECT",
    )


def sample_project_for_app() -> Path:
    """The project `lightcal app` opens without one: the sample in place in a source
    checkout; installed, the user's copy of it (made, or completed, first)."""
    from lightcal_app import server

    from lightcal.resources import sample_project_is_packaged, user_sample_dir, write_sample_project

    path = server.default_project_path()
    if not path.is_file():
        raise sample_project_missing(path)
    if not sample_project_is_packaged():
        return path
    copy = write_sample_project(user_sample_dir(), force=True, source=path.parent)
    if copy.written:
        print(
            f"lightcal app: copied the sample project to {copy.folder} (your changes and "
            "the autosave stay there)",
            flush=True,
        )
    return copy.folder / "project.json"


_HOST_NAME = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)(\.(?!-)[A-Za-z0-9-]{1,63}(?<!-))*\.?")


def check_address(host: str, port: int) -> None:
    """--host is an IP address or a host name (or empty: every interface) and --port a TCP
    port (0: any free one); checked before the project is read and the server started."""
    if not 0 <= port <= 65535:
        raise InputError("--port", f"expected a TCP port from 0 to 65535, got {port}")
    if host in EXPOSED_HOSTS:
        return
    try:
        ipaddress.ip_address(host.strip("[]"))
    except ValueError:
        # (a name's last label is never all digits: 999.1.1.1 is a mistyped address)
        last = host.rstrip(".").rsplit(".", 1)[-1]
        if len(host) > 253 or not _HOST_NAME.fullmatch(host) or last.isdigit():
            raise InputError(
                "--host", f"expected an IP address or a host name, got {host!r}"
            ) from None


def check_files(args: argparse.Namespace, path: Path) -> None:
    """Before the images are read and the kernels compiled: the project loads, --demo's
    truth file matches it, and --session and --state-dir can be written without touching
    an input: the app writes its autosave to --session (and renames a session it cannot
    read to `.bad`), so it must never be the project, its images or the truth file."""
    from lightcal_app.demo_truth import read_truth_lights, truth_path_for

    from lightcal.io.outputs import check_output_file, project_inputs
    from lightcal.io.project import load_project

    project = load_project(path)
    if args.demo:
        truth = read_truth_lights(truth_path_for(path))
        if len(truth) != len(project.lights):
            raise InputError(
                truth_path_for(path),
                f"lights: {len(truth)} true lights but the project has {len(project.lights)}",
            )
    if args.session is not None:
        inputs = project_inputs(project)
        if args.demo:
            inputs.setdefault(truth_path_for(path).resolve(), "the truth file")
        check_output_file(args.session, option="--session", inputs=inputs, inputs_of="the app")
    state = args.state_dir
    if state is not None and (state.exists() or state.is_symlink()) and not state.is_dir():
        raise InputError(state, "--state-dir: is not a folder; expected a folder to write into")


def run(args: argparse.Namespace) -> int:
    from lightcal_app.server import build_app, serve_forever

    from lightcal.cli.progress import ensure_kernels

    check_address(args.host, args.port)
    path = args.project if args.project is not None else sample_project_for_app()
    check_files(args, path)
    if args.host in EXPOSED_HOSTS:
        print(
            f"lightcal app: warning: --host {args.host or '(all)'} exposes the app to every "
            "machine that can reach this one, without authentication; anyone there can "
            "read your data and upload files",
            file=sys.stderr,
        )
    ensure_kernels()
    app = build_app(
        path,
        host=args.host,
        port=args.port,
        demo=args.demo,
        session_path=args.session if args.session is not None else True,
        restore=not args.fresh,
        state_dir=args.state_dir,
        say=lambda text: print(f"lightcal app: {text}", flush=True),
    )

    def announce() -> None:
        print(f"lightcal app: serving {app.state.project.path}", flush=True)
        print(f"lightcal app: open {app.url} in your browser (Ctrl-C stops)", flush=True)

    collector.for_a_server()
    serve_forever(app, on_ready=announce)
    return 0

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
import sys
from pathlib import Path

from lightcal.cli import collector
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
        type=Path,
        help="project file (JSON or YAML); default: the bundled sample project "
        "(sample_data/ of a source checkout; installed: a copy in ~/.local/share/lightcal)",
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default 127.0.0.1, this machine only; 0.0.0.0 exposes "
        "the app to the network without authentication)",
    )
    p.add_argument("--port", type=int, default=8080, help="TCP port (default 8080)")
    p.add_argument(
        "--demo",
        action="store_true",
        help="also show the true light from truth.json beside the project (synthetic data)",
    )
    p.add_argument("--fresh", action="store_true", help="do not restore the autosaved session")
    p.add_argument(
        "--session",
        type=Path,
        help="autosave file (default: <project>.session.json beside the project)",
    )
    p.add_argument(
        "--state-dir",
        type=Path,
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


def run(args: argparse.Namespace) -> int:
    from lightcal_app.server import build_app, serve_forever

    from lightcal.cli.progress import ensure_kernels

    path = args.project if args.project is not None else sample_project_for_app()
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

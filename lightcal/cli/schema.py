"""`lightcal schema`: print the JSON Schema of the project (or result) file."""

from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("schema", help="print the JSON Schema of the project or result file")
    p.add_argument("which", nargs="?", choices=("project", "result"), default="project")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.which == "project":
        from lightcal.io.project import project_schema

        schema = project_schema()
    else:
        from lightcal.io.result_file import result_schema

        schema = result_schema()
    print(json.dumps(schema, indent=2))
    return 0

"""`lightcal board LAYOUT --out board.pdf [--paper a4]`: print a board file at true scale.

A `markers` board gives one page per marker (the marker at its true size with its white
border, its dictionary and id, where its centre goes on the wall, a 100 mm scale bar);
any other board one sheet (`lightcal.capture.board_print`). The PDF is written by
lightcal itself (`lightcal.io.pdf_file`). `--out` is checked before any work as the
other commands check theirs: a .pdf, never the board file, never an existing file
without `--force`.
"""

from __future__ import annotations

import argparse

from lightcal.cli.arguments import path_arg

PAPERS = ("a4", "a3", "a2", "a1", "a0", "letter", "tabloid")
"""`--paper` choices (`lightcal.capture.board_print.PAPER_SIZES_M`)."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "board",
        help="print a board file as a PDF at true scale (a page per marker)",
        description=(
            "Write a PDF of LAYOUT at true scale: for a markers board one page per marker, "
            "with its id, dictionary and where its centre goes on the wall; any other board "
            "on one sheet. Each page has a 100 mm bar: print at 100 % and measure it."
        ),
    )
    p.add_argument("layout", type=path_arg, metavar="LAYOUT", help="the board file")
    p.add_argument("--out", type=path_arg, required=True, help="the PDF to write")
    p.add_argument(
        "--paper",
        choices=PAPERS,
        default="a4",
        help="paper size: portrait, or landscape where only that fits (default a4)",
    )
    p.add_argument("--force", action="store_true", help="replace an existing --out")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from lightcal.capture.board_print import board_pages
    from lightcal.capture.boards import MarkerLayout
    from lightcal.errors import InputError
    from lightcal.io.board_file import read_board
    from lightcal.io.outputs import check_output_file
    from lightcal.io.pdf_file import write_pdf

    # Before any work: --out is a new .pdf (or --force), never the board file.
    inputs = {args.layout.resolve(): "the board file"} if args.layout.is_file() else {}
    check_output_file(
        args.out, option="--out", inputs=inputs, force=args.force, inputs_of="the PDF"
    )
    if args.out.suffix.lower() != ".pdf":
        raise InputError(args.out, f"--out: unsupported suffix {args.out.suffix!r}: expected .pdf")
    board = read_board(args.layout)
    try:
        pages = board_pages(board, paper=args.paper, name=args.layout.name)
    except InputError as exc:
        if exc.source != "paper":
            raise InputError(args.layout, f"{exc.source}: {exc.detail}") from exc
        raise InputError("--paper", exc.detail) from exc
    write_pdf(args.out, pages)
    what = "one per marker" if isinstance(board, MarkerLayout) else "the board on one sheet"
    count = f"{len(pages)} page{'s' if len(pages) > 1 else ''}"
    print(
        f"{count} ({what}, {args.paper}) written to {args.out}: print at 100 % (no fit to "
        "page) and check that each page's bar measures 100 mm"
    )
    return 0

"""`lightcal response BRACKET... --out response.json [--times S...] [--plot FILE]`: fit a
camera's response curve (Debevec & Malik) from an exposure bracket of 8-bit photos, for
projects of JPEG or other 8-bit photos (`sensor.response`). A bracket of grey photos (a
monochrome camera) gives a one-channel curve, which reads grey photos (a three-channel
one refuses them)."""

from __future__ import annotations

import argparse

from lightcal.cli.arguments import path_arg


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "response",
        help="fit a camera response curve from an exposure bracket of 8-bit photos",
        description=(
            "Fit the inverse response of a camera's 8-bit output (JPEG, 8-bit PNG/TIFF) "
            "from photos of one static scene at several exposure times, on a tripod "
            "(Debevec & Malik 1997, OpenCV). The curve makes such photos linear: give it "
            "as sensor.response in a project. Exposure times come from each photo's EXIF, "
            "or from --times."
        ),
    )
    p.add_argument("images", type=path_arg, nargs="+", metavar="IMAGE", help="the bracket")
    p.add_argument("--out", type=path_arg, required=True, help="the curve to write (.json or .npy)")
    p.add_argument(
        "--times",
        type=float,
        nargs="+",
        metavar="S",
        help="each photo's exposure time in seconds, in order (default: from EXIF)",
    )
    p.add_argument("--plot", type=path_arg, help="also draw the curve into this PNG")
    p.add_argument("--force", action="store_true", help="replace an existing --out / --plot")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import math

    from lightcal.cli.progress import console
    from lightcal.errors import InputError
    from lightcal.io.exif import read_exposure
    from lightcal.io.outputs import check_output_file
    from lightcal.io.response_bracket import fit_bracket_curve, read_bracket_image

    # Before any work: every argument, then every photo read.
    n = len(args.images)
    if n < 2:
        raise InputError("IMAGE", f"expected at least 2 photos of an exposure bracket, got {n}")
    if args.times is not None and len(args.times) != n:
        raise InputError(
            "--times", f"expected {n} exposure times, one per photo, got {len(args.times)}"
        )
    if args.times is not None and not all(math.isfinite(t) and t > 0 for t in args.times):
        raise InputError("--times", "expected exposure times in seconds, finite and > 0")
    if len({p.resolve() for p in args.images}) != n:
        raise InputError("IMAGE", "a photo is given twice: expected each photo once")
    inputs = {p.resolve(): "a photo of the bracket" for p in args.images}
    check_output_file(
        args.out, option="--out", inputs=inputs, force=args.force, inputs_of="the fit"
    )
    if args.out.suffix.lower() not in (".json", ".npy"):
        raise InputError(args.out, f"--out: expected a .json or .npy file, got {args.out.name}")
    if args.plot is not None:
        check_output_file(
            args.plot, option="--plot", inputs=inputs, force=args.force, inputs_of="the fit"
        )
        if args.plot.suffix.lower() != ".png":
            raise InputError(args.plot, f"--plot: expected a .png file, got {args.plot.name}")
    images = [read_bracket_image(p) for p in args.images]
    for p, image in zip(args.images[1:], images[1:], strict=True):
        if image.shape != images[0].shape:
            raise InputError(
                p,
                f"{image.shape[1]} x {image.shape[0]} pixels, expected "
                f"{images[0].shape[1]} x {images[0].shape[0]} like {args.images[0].name}",
            )
    times = list(args.times) if args.times is not None else []
    if args.times is None:
        for p in args.images:
            exposure = read_exposure(p)
            if exposure is None or exposure.exposure_time_s is None:
                raise InputError(p, "no exposure time in its EXIF: give every photo's with --times")
            times.append(exposure.exposure_time_s)
    if len(set(times)) < 2:
        raise InputError(
            "--times" if args.times is not None else args.images[0],
            f"every photo has the exposure time {times[0]:g} s: expected a bracket of "
            "different exposure times",
        )
    # Locations spread over the codes (lightcal.io.response_bracket): a regular grid of
    # 300 left a narrow beam's bracket 20 % off between codes 20 and 160.
    curve = fit_bracket_curve(images, times)
    curve.save(args.out)
    codes = (64, 128, 192, 255)
    shown = ", ".join(
        f"{c} -> {curve.values[c].mean() / curve.values[128].mean():.3g}" for c in codes
    )
    console.print(
        f"response of {n} photos ({min(times):g} to {max(times):g} s) written to {args.out}; "
        f"linear value of code {shown} (1 at code 128)",
        highlight=False,
        soft_wrap=True,
    )
    if args.plot is not None:
        from lightcal.io.figures import write_png
        from lightcal.io.response_figure import response_figure

        write_png(args.plot, response_figure(curve, title=f"camera response ({args.out.name})"))
        console.print(f"plot written to {args.plot}", highlight=False, soft_wrap=True)
    return 0

"""Write minimal Bayer DNG files for the raw and EXIF tests (tifffile, no camera needed).

The file is a single uncompressed 16-bit CFA IFD0 with the tags LibRaw needs:
PhotometricInterpretation 32803 (CFA), CFARepeatPatternDim / CFAPattern, DNGVersion,
UniqueCameraModel, Make / Model, BlackLevel (50714, optionally per 2x2 site with
BlackLevelRepeatDim 50713), WhiteLevel (50717), ColorMatrix1 (identity) and, when asked,
AsShotNeutral and the TIFF/EP exposure tags ExposureTime, FNumber and ISOSpeedRatings in IFD0.
LibRaw refuses images smaller than 22 x 22 pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import tifffile

CFA_CODES = {"R": 0, "G": 1, "B": 2}


def write_dng(
    path: Path,
    mosaic: np.ndarray,
    *,
    pattern: str = "RGGB",
    black_level: int | Sequence[int] = 64,
    white_level: int = 4095,
    exposure_time: tuple[int, int] | None = None,
    f_number: tuple[int, int] | None = None,
    iso: int | None = None,
    as_shot_neutral: Sequence[tuple[int, int]] | None = None,
) -> Path:
    """Write `mosaic` (H, W) uint16 as a Bayer DNG.

    Args:
        path: Where to write.
        mosaic: (H, W) uint16 raw values, H and W >= 22.
        pattern: The 2x2 CFA cell, row by row, e.g. "RGGB", "BGGR", "GRBG".
        black_level: One value, or four for the 2x2 cell sites (row by row).
        white_level: WhiteLevel tag.
        exposure_time: ExposureTime as a rational (numerator, denominator).
        f_number: FNumber as a rational.
        iso: ISOSpeedRatings.
        as_shot_neutral: AsShotNeutral (50728), one rational per colour R, G, B; the
            camera white balance gains are their reciprocals.
    """
    mosaic = np.asarray(mosaic, dtype=np.uint16)
    identity = (1, 1, 0, 1, 0, 1, 0, 1, 1, 1, 0, 1, 0, 1, 0, 1, 1, 1)
    tags: list[tuple[int, str, int, Any, bool]] = [
        (271, "s", 0, "lightcal", True),
        (272, "s", 0, "test sensor", True),
        (33421, "H", 2, (2, 2), True),
        (33422, "B", 4, tuple(CFA_CODES[c] for c in pattern), True),
        (50706, "B", 4, (1, 4, 0, 0), True),
        (50707, "B", 4, (1, 1, 0, 0), True),
        (50708, "s", 0, "lightcal test sensor", True),
        (50717, "H", 1, (white_level,), True),
        (50721, "2i", 9, identity, True),
        (50778, "H", 1, (21,), True),
    ]
    if isinstance(black_level, int):
        tags.append((50714, "H", 1, (black_level,), True))
    else:
        tags.append((50713, "H", 2, (2, 2), True))
        tags.append((50714, "H", 4, tuple(black_level), True))
    if exposure_time is not None:
        tags.append((33434, "2I", 1, exposure_time, True))
    if f_number is not None:
        tags.append((33437, "2I", 1, f_number, True))
    if iso is not None:
        tags.append((34855, "H", 1, (iso,), True))
    if as_shot_neutral is not None:
        tags.append((50728, "2I", 3, tuple(v for pair in as_shot_neutral for v in pair), True))
    tifffile.imwrite(path, mosaic, photometric=32803, subfiletype=0, metadata=None, extratags=tags)
    return path

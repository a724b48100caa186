"""Read single image files (PNG, TIFF) as frames of digital numbers.

Only 8- and 16-bit single-channel images are raw frames; their headers are checked before the
pixels are decoded, so a wrong file fails with the file's name and the fix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SchemaError

__all__ = ["IMAGE_SUFFIXES", "read_image"]

#: File suffixes read by :func:`~sunlab.io.from_image_folder` and :func:`read_image`.
IMAGE_SUFFIXES = (".png", ".tif", ".tiff")

_PNG_MODES = {"L": np.uint8, "I;16": np.uint16, "I;16L": np.uint16, "I;16B": np.uint16}


def _image_header(path: Path) -> tuple[tuple[int, ...], np.dtype]:
    """Shape and dtype of an image, from its header only."""
    suffix = path.suffix.lower()
    expected = "a single-channel 8- or 16-bit unsigned PNG or TIFF image"
    fix = "export raw frames as 8- or 16-bit grayscale PNG or TIFF (16-bit for a 10-bit ADC)"
    try:
        if suffix == ".png":
            from PIL import Image

            with Image.open(path) as im:
                mode, (width, height) = im.mode, im.size
            if mode not in _PNG_MODES:
                raise SchemaError(f"image {path.name}", f"PNG mode {mode!r}", expected, fix)
            return (height, width), np.dtype(_PNG_MODES[mode])
        if suffix in (".tif", ".tiff"):
            import tifffile

            with tifffile.TiffFile(path) as tif:
                series = tif.series[0]
                shape, dtype, n_pages = tuple(series.shape), np.dtype(series.dtype), len(tif.pages)
            if n_pages > 1 or len(shape) != 2:
                raise SchemaError(
                    f"image {path.name}", f"a TIFF of shape {shape} ({n_pages} pages)",
                    "one 2-d frame per file", "save one frame per file",
                )
            return shape, dtype
    except SchemaError:
        raise
    except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the file
        raise SchemaError(
            f"image {path.name}", f"unreadable ({type(exc).__name__}: {exc})", expected,
            "the file is corrupt or of another type; export it again",
        ) from exc
    raise SchemaError(
        f"image {path.name}", f"suffix {path.suffix!r}", f"one of {IMAGE_SUFFIXES}", fix
    )


def read_image(path, *, bit_depth: int | None = None) -> np.ndarray:
    """Read one frame from a PNG (Pillow) or TIFF (tifffile) file as a 2-d uint8/uint16 array.

    Parameters
    ----------
    path : str or path-like
        Image file; 16-bit PNGs (Pillow mode ``I;16``) and 16-bit TIFFs give uint16.
    bit_depth : int, optional
        When given, every DN must be below ``2**bit_depth``.

    Returns
    -------
    numpy.ndarray, shape (y, x)
        The frame in DN, indexed ``frame[y, x]`` (y = row, x = column).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib, tifffile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "f.tif"
    >>> tifffile.imwrite(path, np.full((2, 3), 1023, np.uint16))
    >>> read_image(path, bit_depth=10).max()
    np.uint16(1023)
    """
    path = Path(path)
    _, dtype = _image_header(path)
    if dtype not in (np.dtype(np.uint8), np.dtype(np.uint16)):
        raise SchemaError(
            f"image {path.name}", f"pixel type {dtype}", "uint8 or uint16 digital numbers",
            "export raw DN as 8- or 16-bit unsigned integers; float or 32-bit images are not "
            "raw frames",
        )
    try:
        if path.suffix.lower() == ".png":
            from PIL import Image

            with Image.open(path) as im:
                frame = np.asarray(im)
        else:
            import tifffile

            frame = tifffile.imread(path)
    except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the file
        raise SchemaError(
            f"image {path}", f"unreadable pixel data ({type(exc).__name__}: {exc})",
            "a complete single-channel PNG or TIFF image",
            "the file is truncated or corrupt (an interrupted copy or write); copy or export "
            "it again",
        ) from exc
    frame = np.ascontiguousarray(frame, dtype=dtype.newbyteorder("="))
    if bit_depth is not None and frame.size and int(frame.max()) >= 2**bit_depth:
        shift = 16 - bit_depth if dtype.itemsize == 2 else 8 - bit_depth
        raise SchemaError(
            f"image {path.name}", f"maximum {int(frame.max())} DN",
            f"< 2**{bit_depth} = {2**bit_depth} DN for bit_depth={bit_depth}",
            "give the true bit_depth (or None to detect it); if the camera left-aligns its data "
            f"in the word (values in steps of {2**max(shift, 0)}), divide by that step first",
        )
    return frame


def _read_checked(path: Path, shape, dtype, bit_depth):
    frame = read_image(path, bit_depth=bit_depth)
    if frame.shape != shape or frame.dtype != dtype:
        raise SchemaError(
            f"image {path.name}", f"shape {frame.shape}, {frame.dtype}", f"shape {shape}, {dtype}",
            "every frame of a cube has the same size and pixel type",
        )
    return frame


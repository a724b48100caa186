"""Read single image files (PNG, TIFF) as frames of digital numbers.

Only 8- and 16-bit single-channel images are raw frames; their headers are checked before the
pixels are decoded, so a wrong file fails with the file's name and the fix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SchemaError

__all__ = ["read_image"]

#: File suffixes read by :func:`~sunlab.io.open_frames` (a folder of images) and :func:`read_image`.
IMAGE_SUFFIXES = (".png", ".tif", ".tiff")

_PNG_MODES = {"L": np.uint8, "I;16": np.uint16, "I;16L": np.uint16, "I;16B": np.uint16}
_RAW = (np.dtype(np.uint8), np.dtype(np.uint16))


def _image_header(path: Path, *, stack: bool = False) -> tuple[tuple[int, ...], np.dtype, int]:
    """Shape and dtype of one frame of an image, and its number of pages, from the header only.

    A TIFF may hold several frames (pages, or a 3-d series) only with ``stack=True``.
    """
    suffix = path.suffix.lower()
    expected = "a single-channel 8- or 16-bit unsigned PNG or TIFF image"
    fix = "export raw frames as 8- or 16-bit grayscale PNG or TIFF (16-bit for a 10-bit ADC)"
    if suffix not in IMAGE_SUFFIXES:
        raise SchemaError(f"image {path.name}", f"suffix {path.suffix!r}",
                          f"one of {IMAGE_SUFFIXES}", fix)
    try:
        if suffix == ".png":
            from PIL import Image

            with Image.open(path) as im:
                mode, (width, height) = im.mode, im.size
            if mode not in _PNG_MODES:
                raise SchemaError(f"image {path.name}", f"PNG mode {mode!r}", expected, fix)
            return (height, width), np.dtype(_PNG_MODES[mode]), 1
        import tifffile

        with tifffile.TiffFile(path) as tif:
            shapes, dtype = [tuple(s.shape) for s in tif.series], np.dtype(tif.series[0].dtype)
        n_pages = sum(int(np.prod(s[:-2])) for s in shapes)
        if any(len(s) < 2 or s[-2:] != shapes[0][-2:] for s in shapes) or (
                len(shapes[0]) > 3 or (n_pages > 1 and not stack)):
            raise SchemaError(
                f"image {path.name}", f"a TIFF of shapes {shapes} ({n_pages} frames)",
                "one 2-d frame per file, or (in a manifest with a 'page' column) pages of one "
                "frame size", "save one frame per file, or add a 'page' column to the manifest "
                "naming the page (0, 1, ...) of each row")
        return shapes[0][-2:], dtype, n_pages
    except SchemaError:
        raise
    except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the file
        raise SchemaError(f"image {path.name}", f"unreadable ({type(exc).__name__}: {exc})",
                          expected, "the file is corrupt or of another type; export it "
                          "again") from exc


def _raw_dtype(path: Path, dtype) -> None:
    if dtype not in _RAW:
        raise SchemaError(
            f"image {path.name}", f"pixel type {dtype}", "uint8 or uint16 digital numbers",
            "export raw DN as 8- or 16-bit unsigned integers; float or 32-bit images are not "
            "raw frames")


def read_image(
    path, *, bit_depth: int | None = None, page: int | None = None, left_aligned: bool = False
) -> np.ndarray:
    """Read one frame from a PNG (Pillow) or TIFF (tifffile) file as a 2-d uint8/uint16 array.

    Parameters
    ----------
    path : str or path-like
        Image file; 16-bit PNGs (Pillow mode ``I;16``) and 16-bit TIFFs give uint16.
    bit_depth : int, optional
        When given, every DN must be below ``2**bit_depth``.
    page : int, optional
        Frame ``page`` (0-based) of a multi-page TIFF stack (pages in file order; a 3-d
        series counts as its frames). Default: the file holds one frame.
    left_aligned : bool
        The camera writes its ``bit_depth``-bit DN in the top bits of the word (a 12-bit camera
        writing DN x 16 in a 16-bit file): the frame is shifted right by
        ``word bits - bit_depth``, and low bits that are not zero are refused (the data are not
        left-aligned at that depth). Needs ``bit_depth``.

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
    >>> tifffile.imwrite(path, np.full((2, 3), 4095 << 4, np.uint16))
    >>> read_image(path, bit_depth=12, left_aligned=True).max()
    np.uint16(4095)
    """
    path = Path(path)
    _, dtype, n_pages = _image_header(path, stack=page is not None)
    _raw_dtype(path, dtype)
    if page is not None and not 0 <= page < n_pages:
        raise SchemaError(f"image {path.name} page", page, f"a page 0 .. {n_pages - 1} of this "
                          "stack", "correct the manifest's 'page' column (pages count from 0)")
    try:
        frame = _decode(path, page)
    except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the file
        raise SchemaError(
            f"image {path}", f"unreadable pixel data ({type(exc).__name__}: {exc})",
            "a complete single-channel PNG or TIFF image", "the file is truncated or corrupt (an "
            "interrupted copy or write); copy or export it again") from exc
    frame = np.ascontiguousarray(frame, dtype=dtype.newbyteorder("="))
    word = 8 * dtype.itemsize
    if left_aligned:
        if bit_depth is None or not 1 <= bit_depth <= word:
            raise SchemaError(
                "bit_depth", bit_depth, f"the ADC's bit depth (1 .. {word}) for left-aligned "
                "data", "give bit_depth (sensor.json \"bit_depth\", or --bit-depth): left-aligned "
                "data are shifted by the word size minus the bit depth")
        shift = word - int(bit_depth)
        low = frame & np.asarray((1 << shift) - 1, frame.dtype)
        if frame.size and low.any():
            raise SchemaError(
                f"image {path.name}", f"values not multiples of {2**shift} (e.g. "
                f"{int(frame[low > 0][0])})", f"{bit_depth}-bit data left-aligned in {word} bits "
                f"(low {shift} bits zero)", "check bit_depth, or drop left_aligned if the camera "
                "writes right-aligned DN")
        frame = frame >> np.asarray(shift, frame.dtype)
    if bit_depth is not None and frame.size and int(frame.max()) >= 2**bit_depth:
        raise SchemaError(
            f"image {path.name}", f"maximum {int(frame.max())} DN",
            f"< 2**{bit_depth} = {2**bit_depth} DN for bit_depth={bit_depth}",
            "give the true bit_depth (or None to detect it); if the camera left-aligns its data "
            f"in the word (values in steps of {2**max(word - bit_depth, 0)}), say left_aligned "
            "(sensor.json \"left_aligned\": true, or --left-aligned)")
    return frame


def _decode(path: Path, page: int | None) -> np.ndarray:
    """The pixels of a PNG, a one-frame TIFF, or frame ``page`` of a TIFF stack."""
    if path.suffix.lower() == ".png":
        from PIL import Image

        with Image.open(path) as im:
            return np.asarray(im)
    import tifffile

    if page is None:
        return tifffile.imread(path)
    with tifffile.TiffFile(path) as tif:
        if len(tif.pages) == sum(int(np.prod(s.shape[:-2])) for s in tif.series):
            return tif.pages[page].asarray()  # one IFD per frame: read that page only
        for series in tif.series:  # frames packed in 3-d series (shaped or ImageJ files)
            n = int(np.prod(series.shape[:-2]))
            if page < n:
                return series.asarray().reshape((n, *series.shape[-2:]))[page]
            page -= n
    raise IndexError("page beyond the file's frames")  # pragma: no cover - checked above


def _read_checked(path: Path, shape, dtype, bit_depth, page=None, left_aligned=False):
    frame = read_image(path, bit_depth=bit_depth, page=page, left_aligned=left_aligned)
    if frame.shape != shape or frame.dtype != dtype:
        raise SchemaError(f"image {path.name}", f"shape {frame.shape}, {frame.dtype}",
                          f"shape {shape}, {dtype}", "every frame of a cube has the same size and "
                          "pixel type")
    return frame

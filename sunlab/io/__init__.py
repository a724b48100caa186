"""Open and save frame cubes and centroid tables; import a folder of images with a manifest.

One way per step: :func:`open_frames` opens frames from every source (a Zarr store, a NetCDF4
file, a folder of images with its manifest, a TIFF stack), :func:`open_centroids` every centroid
table (Zarr, NetCDF4, a CSV of another tool), :func:`save_frames` and :func:`save_centroids`
write them. One module per concept: ``read`` (the openers), ``write``, ``folder`` (a folder of
images as a cube), ``images`` (one image file), ``sensor`` (``sensor.json``), ``csvtable`` (CSV
tables and manifests), ``calframes`` (master dark, bias and flat), ``chunks`` (a damaged chunk
names itself), ``codec`` (attributes), ``describe`` (:func:`summary`).

Two on-disk formats hold the same datasets (contracts ``frames/1`` and ``centroids/1`` of
``data_schema/``):

* **Zarr v3** (the default; any path not ending in ``.nc``): a directory store, frames chunked one
  frame (or one pose) per chunk, Blosc-compressed (byte shuffle + Zstandard), every chunk
  written, opened lazily as Dask arrays.
* **NetCDF4/HDF5** (``.nc``): one file written with the ``h5netcdf`` engine, frames chunked and
  compressed the same way; uint16 DN survive as uint16.

Nothing lost, nothing silent: every chunk carries a checksum (Zarr: a CRC-32C codec after the
compressor; NetCDF: the HDF5 Fletcher-32 filter on the frames), so a damaged chunk fails to read
with a :class:`sunlab.SunlabError` that names the store, the variable and the chunk; stores
written before checksums still open. Outputs are written to a hidden temporary sibling and
renamed into place (:mod:`sunlab.atomic`): an existing output is replaced only with
``overwrite=True`` and survives a write that fails. Frames read from disk are checked against
the store's ``bit_depth`` chunk by chunk.

Round trips are exact: dtypes, coordinates and attributes come back as they were saved. Attribute
values that NetCDF or Zarr cannot hold natively (booleans, None, lists, dicts, numpy arrays in Zarr)
are stored as JSON text or flat arrays and listed, per dataset or variable, in the attribute
``sunlab_attr_codec``, which the readers use to restore them; other readers see plain text.
Numpy scalar attributes come back as the Python ``int``, ``float`` or ``bool`` of the same value.

Examples
--------
>>> import numpy as np, tempfile, pathlib
>>> from sunlab import io, schema
>>> cube = schema.frames_dataset(np.arange(2 * 3 * 4 * 5, dtype=np.uint16).reshape(2, 3, 4, 5),
...                              alpha=[0.0, 1.0], beta=[0.0, 0.0])
>>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.zarr"
>>> io.save_frames(cube, path)
>>> back = io.open_frames(path)
>>> back.frames.data.chunksize, back.frames.dtype
((1, 1, 4, 5), dtype('uint16'))
>>> bool((back.frames == cube.frames).all())
True
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)

"""Open and save frame cubes and centroid tables; import a folder of images with a manifest.

One module per concept, every public name re-exported here:

* :mod:`sunlab.io.write` -- :func:`save_frames`, :func:`save_centroids` (Zarr or NetCDF4);
* :mod:`sunlab.io.read` -- :func:`open_frames`, :func:`open_centroids`, :func:`open_dataset`;
* :mod:`sunlab.io.csvtable` -- :func:`centroids_from_csv`, centroid tables of other tools;
* :mod:`sunlab.io.chunks` -- a damaged, missing or out-of-range chunk names itself;
* :mod:`sunlab.io.codec` -- exact round trips of attributes;
* :mod:`sunlab.io.images` -- :func:`read_image`, one PNG or TIFF frame;
* :mod:`sunlab.io.folder` -- :func:`from_image_folder`, :func:`example_folder`;
* :mod:`sunlab.io.sensor` -- :func:`read_sensor_json`, the checked ``sensor.json`` of a folder;
* :mod:`sunlab.io.calframes` -- master dark, bias and flat frames
  (:func:`with_calibration_frames`) and the lazy correction (:func:`corrected_frames`);
* :mod:`sunlab.io.lab` -- :func:`import_folder`: a lab's folder, sensor.json and calibration
  frames as one cube (``sunlab import``);
* :mod:`sunlab.io.describe` -- :func:`summary`.

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

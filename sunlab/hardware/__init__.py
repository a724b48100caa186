"""The lab hardware: drive a two-axis rotation platform and a camera, and record resumable runs.

- :class:`ESP300`: a Newport ESP300/ESP301 driver over pyserial (any ``serial_for_url`` URL),
  with timeouts, bounded retries, error decoding, limit checks and a settle time, in
  :mod:`sunlab.hardware.esp` with the wire protocol it speaks; :func:`open_stage` opens one
  from a URL (``fake://``, ``socket://``, a device path) or a lab's own stage by its entry point.
- ``fake.FakeESP``: the same protocol over a pseudo-terminal or loopback TCP, backed by the
  virtual bench's platform model, with fault injection.
- ``cameras.Camera``: the camera protocol (``cameras.ControlledCamera`` adds exposure, ROI and dark
  frames); :class:`SimCamera` renders from the virtual bench, :class:`FolderCamera` picks up
  the image files a real camera writes; a lab's own class is opened by :func:`open_camera`
  (``module:Class`` or the entry point group ``sunlab.cameras``).
- :func:`acquire`: plan -> move -> settle -> N shots -> a pre-allocated Zarr store, one pose at a
  time, resumable after a crash or Ctrl-C.

This subpackage talks to hardware; ``import sunlab`` does not import it.

Examples
--------
>>> from sunlab import hardware
>>> stage = hardware.open_stage("fake://?velocity=1e4", retry_delay_s=0.0, poll_s=0.001)
>>> stage.move_to(-16.5, 2.0)
(-16.5, 2.0)
>>> stage.close()
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)

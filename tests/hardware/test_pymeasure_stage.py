"""A client nobody here wrote: pymeasure's own ESP300 driver drives the fake controller through
pyvisa-py, over loopback TCP (a ``TCPIP::...::SOCKET`` resource) and over the pseudo-terminal
(an ``ASRL/dev/pts/N::INSTR`` resource). It identifies the controller and the positioner, reads
units, motor state and limits, moves two axes, waits for the stop (``WS``), reads the positions
back (``TP`` without ``?``, as pymeasure sends it), homes (``OR``), defines home (``DH``) and
reads the error buffer (``TE?``).
"""

from __future__ import annotations

import pytest
from pymeasure.instruments.newport.esp300 import ESP300 as PymeasureESP300
from pymeasure.instruments.newport.esp300 import AxisError, GeneralError

from sunlab.hardware import FakeESP

# pymeasure's ESP300 mixes in SCPIUnknownMixin, which warns at every construction that it does
# not know whether the instrument speaks SCPI (the ESP300 does not); the warning is about
# pymeasure's class, not about anything this test or sunlab does, so only it is ignored.
pytestmark = pytest.mark.filterwarnings(
    "ignore:It is not known whether this device support SCPI commands:FutureWarning"
)


@pytest.fixture
def fake():
    # a finite speed: a move takes 0.6 s of controller time, and only pymeasure's WS (wait for
    # stop) makes the reads that follow see it finished; no test waits on the wall clock
    controller = FakeESP(velocity_deg_s=20.0)
    yield controller
    controller.close()


@pytest.fixture(params=["tcp", "pty"])
def esp(request, fake):
    """pymeasure's ESP300 on a pyvisa-py resource served by the fake."""
    if request.param == "tcp":
        port = fake.serve_tcp().rsplit(":", 1)[1]
        resource = f"TCPIP::127.0.0.1::{port}::SOCKET"
    else:
        resource = f"ASRL{fake.serve_pty()}::INSTR"
    instrument = PymeasureESP300(resource, visa_library="@py", read_termination="\r\n",
                                 write_termination="\r", timeout=2000)
    yield instrument
    instrument.adapter.close()


def test_pymeasure_identifies_moves_and_reads_back(fake, esp):
    assert esp.ask("VE?").startswith("ESP301 Version")
    assert esp.x.ask("ID?") == "URS100BCC, SN0001"
    assert (esp.x.units, esp.x.enabled) == ("degree", True)
    assert (esp.x.left_limit, esp.x.right_limit) == (-170.0, 170.0)

    n0 = len(fake.received)
    esp.x.position = 12.5
    esp.y.position = -3.25
    assert not esp.x.motion_done  # the move is under way
    esp.x.wait_for_stop()
    esp.y.wait_for_stop()
    assert esp.x.motion_done and esp.y.motion_done
    assert (esp.x.position, esp.y.position) == (12.5, -3.25)
    assert esp.errors == [] and esp.error == 0
    # what pymeasure sent, as the fake received it: nothing refused, no error queued
    assert fake.received[n0:] == ["1PA12.5", "2PA-3.25", "1MD?", "1WS0", "1MD?", "2WS0", "2MD?",
                                  "1MD?", "2MD?", "1TP", "2TP", "TE?", "TE?"]


def test_pymeasure_homes_defines_home_and_toggles_the_motor(esp):
    esp.y.position = 4.0
    esp.y.wait_for_stop()
    esp.y.home(1)  # 2OR1
    esp.y.wait_for_stop()
    assert esp.y.position == 0.0
    esp.y.define_position(3.0)  # 2DH3: here reads 3
    assert esp.y.position == 3.0
    esp.y.zero()  # 2DH
    assert esp.y.position == 0.0
    esp.x.disable()
    assert esp.x.enabled is False
    esp.x.enable()
    assert esp.x.enabled is True
    assert esp.errors == []


def test_pymeasure_reads_the_controller_errors(esp):
    esp.x.position = 171.0  # beyond the right software limit: refused, error 106
    esp.write("1XX")  # no such command: error 6
    errors = esp.errors
    assert [type(e) for e in errors] == [AxisError, GeneralError]
    assert (errors[0].axis, errors[0].message) == ("1", "POSITIVE SOFTWARE LIMIT DETECTED")
    assert errors[1].message == "COMMAND DOES NOT EXIST"
    assert esp.error == 0

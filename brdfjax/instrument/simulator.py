"""A simulated goniometer behind a real pseudo-terminal, speaking `brdfjax.instrument.protocol`.

Physical model
--------------
The source beam (flux ``P``) falls wholly on the sample; the detector subtends a small solid
angle ``omega`` and sees the whole lit spot. The power it collects is ``P f_r cos(theta_r)
omega`` (the radiance ``f_r E`` of the spot, times its projected area, times ``omega``; the
irradiance ``E`` times the spot's area is ``P`` at any incidence), so its voltage is

    V = gain * f_r(theta_i, theta_r, phi_r) * cos(theta_r)

with ``gain = responsivity * P * omega`` (volts per unit of projected BRDF, ``--gain``). The
PTFE reference plate is Lambertian with hemispherical reflectance ``rho_ref``, so its BRDF is
``rho_ref / pi`` and ``V_ref = gain * rho_ref / pi * cos(theta_r)``. The ratio at one
geometry is then exactly the reference-sample method of Eq. (7)-(8):
``f_sample = (V_sample / V_ref) * rho_ref / pi``.

Each integration of ``ms`` milliseconds adds Gaussian noise of relative standard deviation
``noise * sqrt(10 ms / ms)`` (``--noise`` is the relative noise of a 10 ms integration; a
longer integration averages more photons). The noise of a reading is drawn from a generator
seeded by ``(seed, target, A, B, C, count, ms)``: the same reading at the same geometry gives
the same voltages whatever was read before, so an interrupted and resumed acquisition
matches an uninterrupted one exactly.

The detector arm shadows the source beam when the two directions are less than
`BLOCKED_DEGREES` apart: ``READ`` answers ``ERR BLOCKED`` there. Motors travel at
``--motor-speed`` deg/s and the sample changer takes ``--changer-seconds``.

Faults (for tests) are applied to each line independently: ``--drop-rate`` deletes one byte,
``--corrupt-rate`` replaces one byte (both on received commands, as line noise on the way in,
and on sent replies), ``--stall-rate`` delays a reply line by ``--stall-seconds``, and
``--disconnect-after N`` answers N commands and hangs up (closes the pseudo-terminal and
exits) when the next arrives. The fault generator is seeded by ``--seed`` too.
"""

from __future__ import annotations

import math
import os
import random
import select
import sys
import termios
import time
import tty
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from brdfjax.instrument import protocol
from brdfjax.instrument.protocol import Message, encode, source_detector_angle

MODEL = "brdfjax-simulator"
SERIAL_NUMBER = "SIM-0001"
FIRMWARE = "1.0"
MOTOR_LIMITS = {"A": (0.0, 180.0), "B": (0.0, 80.0), "C": (-87.0, 87.0)}
# Half the angle the detector head subtends seen from the sample: closer than this to the
# source direction, the head is in the incident beam.
BLOCKED_DEGREES = 3.0
# The default motor speed (deg/s, every motor) and sample-changer swap time (s); the cost
# model of `brdfjax.instrument.design`'s routes.
MOTOR_SPEED = 20.0
CHANGER_SECONDS = 1.0
NOISE_INTEGRATION_MS = 10.0  # the integration time at which --noise is the relative noise


class NoData(ValueError):
    """The data-driven sample has no value at the asked geometry."""


class ModelSample:
    """A sample whose BRDF is a model (the five-parameter model of Eq. 5 by default) with
    fixed parameters."""

    def __init__(self, params, model: str = "five"):
        import functools

        import jax

        from brdfjax.models.paper import brdf

        self.params = np.asarray(params, dtype=float)
        self._brdf = jax.jit(functools.partial(brdf, model=model))
        self.brdf(10.0, 10.0, 0.0)  # compile now, not in the middle of the first READ

    def brdf(self, theta_i: float, theta_r: float, phi_r: float) -> float:
        """f_r in 1/sr at angles in degrees."""
        return float(self._brdf(self.params, *np.radians([theta_i, theta_r, phi_r])))


class DataSample:
    """A sample whose BRDF is interpolated from in-plane measurements.

    Linear in the signed reflection angle (negative: source side) along each measured
    incidence, then linear in the incidence between the two nearest measured incidences.
    Outside the measured incidences, or off the plane of incidence, or outside the angles
    measured at either incidence, there is no value (`NoData`): the simulator answers
    ``ERR NODATA`` rather than extrapolate.
    """

    def __init__(self, data):
        if not data.in_plane:
            raise ValueError(f"{data.name}: the simulator interpolates in-plane data only "
                             "(phi_r = 0 or 180 deg)")
        incidences = np.degrees(data.theta_i)
        signed = np.where(np.cos(data.phi_r) < 0, 1.0, -1.0) * np.degrees(data.theta_r)
        self.incidences = np.unique(np.round(incidences, 6))
        self.curves = []
        for incidence in self.incidences:
            pick = np.abs(incidences - incidence) < 1e-6
            order = np.argsort(signed[pick])
            self.curves.append((signed[pick][order], data.brdf[pick][order]))

    def brdf(self, theta_i: float, theta_r: float, phi_r: float) -> float:
        """f_r in 1/sr at angles in degrees, interpolated; `NoData` where there is none."""
        if abs(math.sin(math.radians(phi_r))) > 1e-9:
            raise NoData(f"phi_r = {phi_r:g} deg is off the plane of the data")
        signed = theta_r if math.cos(math.radians(phi_r)) < 0 else -theta_r
        incidences = self.incidences
        if not incidences[0] - 1e-6 <= theta_i <= incidences[-1] + 1e-6:
            raise NoData(f"incidence {theta_i:g} deg outside the data's "
                         f"{incidences[0]:g} to {incidences[-1]:g} deg")
        upper = min(int(np.searchsorted(incidences, theta_i - 1e-6)), len(incidences) - 1)
        if abs(incidences[upper] - theta_i) < 1e-6:
            return self._along(upper, signed)
        lower = upper - 1
        weight = (theta_i - incidences[lower]) / (incidences[upper] - incidences[lower])
        return (1 - weight) * self._along(lower, signed) + weight * self._along(upper, signed)

    def _along(self, index: int, signed: float) -> float:
        angles, values = self.curves[index]
        if not angles[0] <= signed <= angles[-1]:
            raise NoData(f"reflection angle {signed:g} deg outside the data at incidence "
                         f"{self.incidences[index]:g} deg")
        return float(np.interp(signed, angles, values))


@dataclass(frozen=True)
class Faults:
    """Fault injection rates (per line) and the disconnect; all off by default."""

    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    stall_rate: float = 0.0
    stall_seconds: float = 1.0
    disconnect_after: int | None = None

    def __post_init__(self):
        for name in ("drop_rate", "corrupt_rate", "stall_rate"):
            if not 0 <= getattr(self, name) < 1:
                raise ValueError(f"{name} must be in [0, 1), got {getattr(self, name)}")


class Device:
    """The instrument's state and its answers to commands, without any I/O.

    Args:
        sample: a `ModelSample` or `DataSample`.
        reference_reflectance: the PTFE plate's hemispherical reflectance ``rho_ref``.
        gain: volts per unit of projected BRDF (see the module docstring).
        noise: relative noise of one 10 ms integration.
        seed: seeds the detector noise.
        motor_speed: degrees per second, every motor.
        changer_seconds: time the sample changer takes to swap.
        baud: the device's line speed (reported by ``IDN?``).
        wavelength_nm: the source's wavelength (reported by ``IDN?``).
    """

    def __init__(self, sample, *, reference_reflectance=0.99, gain=3.0, noise=0.01, seed=0,
                 motor_speed=MOTOR_SPEED, changer_seconds=CHANGER_SECONDS, baud=115200,
                 wavelength_nm=1060.0):
        if not 0 < reference_reflectance <= 1:
            raise ValueError(f"reference reflectance {reference_reflectance} not in (0, 1]")
        if gain <= 0 or noise < 0 or motor_speed <= 0 or changer_seconds < 0 or seed < 0:
            raise ValueError("gain and motor speed must be positive; noise, changer time "
                             "and seed not negative")
        self.sample, self.reference_reflectance = sample, reference_reflectance
        self.gain, self.noise, self.seed = gain, noise, seed
        self.motor_speed, self.changer_seconds = motor_speed, changer_seconds
        self.baud, self.wavelength_nm = baud, wavelength_nm
        self.position = dict.fromkeys(MOTOR_LIMITS, 0.0)
        self.homed, self.target = False, "SAMPLE"
        self.counts = {"moves": 0, "reads": 0, "commands": 0}

    def execute(self, command: Message) -> tuple[tuple[str, ...], float]:
        """Run one command: its final reply (``("OK", ...)`` or ``("ERR", code, text)``)
        and the seconds it takes."""
        self.counts["commands"] += 1
        handler = self._HANDLERS.get(command.word)
        if handler is None:
            return ("ERR", "UNKNOWN", f"no command {command.word}"), 0.0
        expected = handler.__code__.co_argcount - 1  # the handler's arguments after self
        if len(command.args) != expected:
            text = f"{command.word} takes {expected} argument(s), got {len(command.args)}"
            return ("ERR", "ARGS", text), 0.0
        try:
            return handler(self, *command.args)
        except _Refusal as refusal:
            return ("ERR", refusal.code, refusal.text), 0.0

    def _identify(self):
        return ("OK", MODEL, SERIAL_NUMBER, FIRMWARE, str(self.baud),
                f"{self.wavelength_nm:g}"), 0.0

    def _limits(self, motor):
        low, high = MOTOR_LIMITS[_motor(motor)]
        return ("OK", motor, f"{low:g}", f"{high:g}"), 0.0

    def _home(self):
        seconds = max(abs(p) for p in self.position.values()) / self.motor_speed
        self.position = dict.fromkeys(MOTOR_LIMITS, 0.0)
        self.homed = True
        self.counts["moves"] += 1
        return ("OK",), seconds

    def _move(self, motor, degrees):
        motor, degrees = _motor(motor), _number(degrees)
        low, high = MOTOR_LIMITS[motor]
        if not low <= degrees <= high:
            raise _Refusal("RANGE", f"motor {motor} to {degrees:g} deg: outside its range "
                                    f"{low:g} to {high:g} deg")
        if not self.homed:
            raise _Refusal("NOTHOMED", "send HOME first")
        degrees = round(degrees, 2)  # the motors step in 0.01 deg
        seconds = abs(degrees - self.position[motor]) / self.motor_speed
        self.position[motor] = degrees
        self.counts["moves"] += 1
        return ("OK", motor, f"{degrees:.2f}"), seconds

    def _report_position(self, motor):
        motor = _motor(motor)
        return ("OK", motor, f"{self.position[motor]:.2f}"), 0.0

    def _select(self, target):
        if target not in protocol.TARGETS:
            raise _Refusal("ARGS", f"SELECT {' or '.join(protocol.TARGETS)}")
        seconds = self.changer_seconds if target != self.target else 0.0
        self.target = target
        self.counts["moves"] += 1
        return ("OK", target), seconds

    def _read(self, count, milliseconds):
        count, milliseconds = int(_number(count)), _number(milliseconds)
        if count < 1 or not milliseconds > 0:
            raise _Refusal("ARGS", "READ <count >= 1> <ms > 0>")
        if not self.homed:
            raise _Refusal("NOTHOMED", "send HOME first")
        a, b, c = (self.position[m] for m in "ABC")
        if source_detector_angle(b, a, c) < BLOCKED_DEGREES:
            raise _Refusal("BLOCKED", f"the detector at C = {c:g} deg is in the source beam")
        volts = self.gain * self._brdf_in_beam() * math.cos(math.radians(abs(c)))
        relative = self.noise * math.sqrt(NOISE_INTEGRATION_MS / milliseconds)
        key = [self.seed, protocol.TARGETS.index(self.target),
               *(round(100 * x) + 100_000 for x in (a, b, c)), count, round(1000 * milliseconds)]
        samples = volts * (1 + relative * np.random.default_rng(key).standard_normal(count))
        std = float(np.std(samples, ddof=1)) if count > 1 else 0.0
        self.counts["reads"] += 1
        return ("OK", f"{np.mean(samples):.9e}", f"{std:.9e}", str(count)), \
            count * milliseconds / 1000

    def _brdf_in_beam(self) -> float:
        if self.target == "REFERENCE":
            return self.reference_reflectance / math.pi
        theta_r, phi_r = protocol.detector_direction(self.position["A"], self.position["C"])
        try:
            return self.sample.brdf(self.position["B"], theta_r, phi_r)
        except NoData as missing:
            raise _Refusal("NODATA", str(missing)) from None

    def _status(self):
        fields = [f"homed={int(self.homed)}", f"target={self.target}"]
        fields += [f"{m}={p:.2f}" for m, p in self.position.items()]
        fields += [f"{k}={v}" for k, v in self.counts.items()]
        return ("OK", *fields), 0.0

    _HANDLERS: ClassVar[dict] = {"IDN?": _identify, "LIMITS?": _limits, "HOME": _home, "MOVE": _move,
                 "POS?": _report_position, "SELECT": _select, "READ": _read,
                 "STATUS?": _status}


class _Refusal(Exception):
    def __init__(self, code: str, text: str):
        super().__init__(text)
        self.code, self.text = code, text


def _motor(name: str) -> str:
    if name not in MOTOR_LIMITS:
        raise _Refusal("ARGS", f"no motor {name!r}; motors are {', '.join(MOTOR_LIMITS)}")
    return name


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _Refusal("ARGS", f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise _Refusal("ARGS", f"{text!r} is not finite")
    return value


@dataclass
class _Running:
    """The command in progress: its line, its final reply and when it is done."""

    line: bytes
    reply: bytes
    done_at: float


class Server:
    """Serves a `Device` on the master side of a pseudo-terminal.

    The host opens the slave side, whose path `path` holds. The server keeps the slave open
    itself, so a host may close the port and open it again.
    """

    def __init__(self, device: Device, faults: Faults = Faults(), seed: int = 0):
        self.speed = getattr(termios, f"B{device.baud}", None)
        if self.speed is None:
            raise ValueError(f"{device.baud} is not a standard baud rate")
        self.device, self.faults = device, faults
        self.random = random.Random(seed)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no line editing until the host sets its own
        attributes = termios.tcgetattr(self.slave)
        attributes[4] = attributes[5] = self.speed  # input and output speed
        termios.tcsetattr(self.slave, termios.TCSANOW, attributes)
        self.path = os.ttyname(self.slave)
        self.last: tuple[bytes, bytes] | None = None  # last command line, its final reply
        self.running: _Running | None = None
        self.answered = 0

    def serve_forever(self) -> None:
        """Answer lines until killed, or until the disconnect fault hangs up."""
        buffer = b""
        try:
            while True:
                wait = None if self.running is None else max(
                    0.0, self.running.done_at - time.monotonic())
                readable, _, _ = select.select([self.master], [], [], wait)
                self._finish_if_done()
                if not readable:
                    continue
                buffer += os.read(self.master, 4096)
                *lines, buffer = buffer.split(b"\n")
                for line in lines:
                    if not self._receive(line + b"\n"):
                        return
        finally:
            os.close(self.master)
            os.close(self.slave)

    def _finish_if_done(self) -> None:
        if self.running is not None and time.monotonic() >= self.running.done_at:
            self._send(self.running.reply)
            self.last = (self.running.line, self.running.reply)
            self.running = None

    def _receive(self, line: bytes) -> bool:
        """Handle one received line; False when the disconnect fault hangs up."""
        if termios.tcgetattr(self.slave)[4] != self.speed:
            self._send(bytes(b | 0x80 for b in encode(0, "ERR", "BAUD")[:-1]) + b"\n")
            return True
        line = self._damage(line)
        try:
            command = protocol.decode(line)
        except protocol.FrameError as problem:
            self._send(encode(protocol.NAK_SEQ, "ERR", "CHECKSUM", str(problem)))
            return True
        if self.running is not None:
            if line == self.running.line:
                remaining = max(0.0, self.running.done_at - time.monotonic())
                self._send(encode(command.seq, "BUSY", f"{remaining:.3f}"))
            else:
                self._send(encode(command.seq, "ERR", "BUSY", "a command is running"))
            return True
        if self.last is not None and line == self.last[0]:
            self._send(self.last[1])
            return True
        if self.faults.disconnect_after is not None \
                and self.answered >= self.faults.disconnect_after:
            print(f"simulator: hanging up after {self.answered} commands (fault injection)",
                  file=sys.stderr, flush=True)
            return False
        self.answered += 1
        reply, seconds = self.device.execute(command)
        framed = encode(command.seq, *reply)
        if seconds > 0:
            self._send(encode(command.seq, "BUSY", f"{seconds:.3f}"))
            self.running = _Running(line, framed, time.monotonic() + seconds)
        else:
            self._send(framed)
            self.last = (line, framed)
        return True

    def _send(self, line: bytes) -> None:
        if self.random.random() < self.faults.stall_rate:
            time.sleep(self.faults.stall_seconds)
        os.write(self.master, self._damage(line))

    def _damage(self, line: bytes) -> bytes:
        """``line`` with one byte dropped and/or one replaced, at the fault rates."""
        if self.random.random() < self.faults.drop_rate:
            k = self.random.randrange(len(line))
            line = line[:k] + line[k + 1:]
        if line and self.random.random() < self.faults.corrupt_rate:
            k = self.random.randrange(len(line))
            replacement = self.random.choice([c for c in b"0123456789ABCDEF *OKR"
                                              if c != line[k]])
            line = line[:k] + bytes([replacement]) + line[k + 1:]
        return line

"""The goniometer's line protocol: framing, checksums, replies, commands and motors.

The paper's instrument (Section 3) turns the sample and the light source with three motors,
A, B and C, reads a detector voltage, and converts voltages to BRDF by the reference-sample
method of Eq. (7)-(8). The paper does not say what each motor turns, nor how the instrument
talks to a computer; this module is brdfjax's definition of both, shared by the driver
(`brdfjax.instrument.driver`) and the simulator (`brdfjax.instrument.simulator`).

Lines
-----
Every line, in both directions, is printable ASCII ending in a newline::

    <seq> <WORD> [<arg> ...]*<crc>\\n

``seq`` is a decimal number from 1 to 999999 chosen by the host (0 only in a NAK, below);
the payload is everything before ``*``; ``crc`` is its CRC-16/CCITT-FALSE (polynomial
0x1021, initial value 0xFFFF: ``binascii.crc_hqx(payload, 0xFFFF)``) as four upper-case hex
digits. Fields are separated by single spaces; no field holds ``*``. A CRC-16 catches every
error burst up to 16 bits long (so every corrupted byte) and all but 1 in 65536 of the rest.

Replies
-------
::

    <seq> OK [<value> ...]        done; the values each command lists below
    <seq> ERR <CODE> <text>       refused; the device changed nothing
    <seq> BUSY <seconds>          accepted and working: the final reply follows in about
                                  <seconds> (sent first by commands that take time)
    0 ERR CHECKSUM <text>         a NAK: the device received a line that failed its checksum

Every command gets exactly one final reply, ``OK`` or ``ERR``. The device runs one command
at a time: any other command arriving meanwhile is answered ``ERR BUSY``.

Retries are idempotent. The host resends a command, with the same ``seq``, when no valid
reply came within its timeout, when a reply failed its checksum, or on a NAK. The device
remembers its last command line and its final reply: a line identical to it (same ``seq``,
same text) is not executed again; the device answers ``BUSY <remaining>`` while it is still
running, and repeats the final reply once it is done. Any other line is a new command. A
replay is always correct: nothing ran in between. The host ignores replies whose ``seq`` is
not that of its current command (late answers to an earlier try).

Commands
--------
=============================  ===================================================
``IDN?``                       ``OK <model> <serial> <firmware> <baud> <wavelength_nm>``
``LIMITS? <motor>``            ``OK <motor> <min_deg> <max_deg>``
``HOME``                       ``OK``: every motor to 0 deg; needed once after power-up
``MOVE <motor> <deg>``         ``OK <motor> <deg>`` on arrival; ``ERR RANGE`` outside the
                               motor's limits, ``ERR NOTHOMED`` before ``HOME``
``POS? <motor>``               ``OK <motor> <deg>``
``SELECT SAMPLE|REFERENCE``    ``OK <target>``: the sample changer puts the sample or the
                               PTFE reference plate in the beam
``READ <count> <ms>``          ``OK <mean_V> <std_V> <count>``: ``count`` integrations of
                               ``ms`` milliseconds each; ``std_V`` is their sample standard
                               deviation (0 when count is 1); ``ERR BLOCKED`` where the
                               detector arm would shadow the source beam
``STATUS?``                    ``OK homed=<0|1> target=<T> A=<deg> B=<deg> C=<deg>
                               moves=<k> reads=<k> commands=<k>`` (``moves`` counts the
                               executed HOME, MOVE and SELECT commands)
=============================  ===================================================

Error codes: ``CHECKSUM``, ``UNKNOWN`` (no such command), ``ARGS`` (wrong arguments),
``RANGE``, ``NOTHOMED``, ``BLOCKED``, ``BUSY``, ``NODATA`` (a data-driven simulator has no
data at that geometry).

Motors
------
- **A**, 0 to 180 deg: turns the detector arm's plane about the sample normal; 0 is the
  plane of incidence.
- **B**, 0 to 80 deg: the source arm; its angle is the incidence zenith ``theta_i``.
- **C**, -87 to 87 deg: the detector arm, a signed zenith angle in its plane: positive
  toward the specular side, negative toward the source.

So the detector looks along ``theta_r = |C|``, ``phi_r = A + 180 deg`` for ``C > 0`` and
``phi_r = A`` for ``C <= 0`` (the project's convention: ``phi_r = 180`` is the specular
half of the plane of incidence). The limits are those of `brdfjax.instrument.simulator`;
a host asks the instrument (``LIMITS?``) rather than assuming them.

Baud rate
---------
A serial line at the wrong baud rate delivers garbage both ways. A pseudo-terminal has no
line speed, but it stores the speed the host sets, so the simulator compares it with its own
before each line: at the wrong speed it executes nothing and answers each line with a line of
bytes that do not frame (a NAK with every byte's high bit set). The driver reports such
replies as a probable baud-rate mismatch.
"""

from __future__ import annotations

import binascii
import math
from dataclasses import dataclass

MAX_SEQ = 999_999
NAK_SEQ = 0
TARGETS = ("SAMPLE", "REFERENCE")
MOTOR_NAMES = {"A": "detector-arm azimuth", "B": "source arm (incidence)",
               "C": "detector arm (signed reflection zenith)"}


class FrameError(ValueError):
    """A received line is not a valid frame (bad checksum, no terminator, not ASCII...)."""


@dataclass(frozen=True)
class Message:
    """One decoded line: a command (``word`` is the command) or a reply (OK, ERR, BUSY)."""

    seq: int
    word: str
    args: tuple[str, ...] = ()


def checksum(payload: bytes) -> str:
    """CRC-16/CCITT-FALSE of ``payload`` as four upper-case hex digits."""
    return f"{binascii.crc_hqx(payload, 0xFFFF):04X}"


def clean_field(text: str) -> str:
    """``text`` made safe for a frame: printable ASCII, no ``*``, no newline."""
    return "".join(c if " " <= c <= "~" and c != "*" else "?" for c in text)


def encode(seq: int, word: str, *args) -> bytes:
    """The framed line ``<seq> <word> <args>*<crc>\\n``."""
    if not 0 <= seq <= MAX_SEQ:
        raise ValueError(f"sequence number {seq} outside 0 to {MAX_SEQ}")
    payload = " ".join([str(seq), word, *(clean_field(str(a)) for a in args)]).encode("ascii")
    return payload + b"*" + checksum(payload).encode("ascii") + b"\n"


def decode(line: bytes) -> Message:
    """The message in one received line; `FrameError` says why a line is not one."""
    if not line.endswith(b"\n"):
        raise FrameError("no line terminator (a partial line)")
    try:
        text = line[:-1].decode("ascii")
    except UnicodeDecodeError:
        raise FrameError("bytes that are not ASCII") from None
    payload, star, crc = text.rpartition("*")
    if not star:
        raise FrameError("no checksum")
    if crc != checksum(payload.encode("ascii")):
        raise FrameError(f"checksum {crc!r} does not match the line")
    fields = payload.split(" ")
    if len(fields) < 2 or not fields[0].isdigit() or not fields[1]:
        raise FrameError("not '<seq> <WORD> ...'")
    return Message(int(fields[0]), fields[1], tuple(fields[2:]))


def detector_direction(azimuth_a: float, signed_c: float) -> tuple[float, float]:
    """(theta_r, phi_r) in degrees of the detector at motor angles A and C (degrees)."""
    phi = azimuth_a + 180.0 if signed_c > 0 else azimuth_a
    return abs(signed_c), phi % 360.0


def source_detector_angle(incidence_b: float, azimuth_a: float, signed_c: float) -> float:
    """Angle in degrees between the directions to the source and to the detector."""
    theta_r, phi_r = (math.radians(x) for x in detector_direction(azimuth_a, signed_c))
    theta_i = math.radians(incidence_b)
    cosine = (math.sin(theta_i) * math.sin(theta_r) * math.cos(phi_r)
              + math.cos(theta_i) * math.cos(theta_r))
    return math.degrees(math.acos(max(-1.0, min(1.0, cosine))))

"""The host side of `brdfjax.instrument.protocol`, on pyserial.

`Instrument` opens a serial port and sends one command at a time. It resends a command (same
sequence number, so the instrument does not run it twice) when no valid reply comes within
``timeout`` seconds, when a reply fails its checksum, or when the instrument reports that the
command arrived damaged, up to ``retries`` times. A ``BUSY <seconds>`` reply extends the
wait. Every failure raises an `InstrumentError` (an `OSError`, which the CLI reports in one
line) that says what was sent and what came back, or that nothing did.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Self

import serial

from brdfjax.instrument import protocol

POLL_SECONDS = 0.02  # how long one read of the port blocks; bounds the reply latency


class InstrumentError(OSError):
    """The instrument did not answer as the protocol says."""


class PortError(InstrumentError):
    """The serial port could not be opened (no such device, busy, no permission)."""


class NoAnswerError(InstrumentError):
    """Nothing, or only part of a line, came back to a command after every retry."""


class GarbledError(InstrumentError):
    """Replies came back but failed their checksums after every retry (wrong baud rate?)."""


class DisconnectedError(InstrumentError):
    """The instrument went away (the port reported an I/O error or hang-up)."""


class RefusedError(InstrumentError):
    """The instrument answered ``ERR``: ``code`` and ``text`` say why."""

    def __init__(self, message: str, code: str, text: str):
        super().__init__(message)
        self.code, self.text = code, text


@dataclass
class _Heard:
    """What came back to one command over its tries, for the error message."""

    garbled: int = 0
    last_garbled: tuple = ()
    naks: int = 0
    partial: bool = False


@dataclass(frozen=True)
class Reading:
    """One detector reading: the mean of ``count`` integrations, and their spread.

    Attributes:
        volts: mean voltage.
        std: sample standard deviation of the integrations (0 for a single one).
        count: how many integrations were averaged.
    """

    volts: float
    std: float
    count: int


class Instrument:
    """A goniometer on a serial port.

    Args:
        port: the device path (``/dev/ttyUSB0``, or the simulator's ``/dev/pts/N``).
        baud: the line speed; it must be the instrument's.
        timeout: seconds to wait for a reply (beyond what a ``BUSY`` announces).
        retries: how many times a command is resent before giving up.

    Raises:
        PortError: when the port cannot be opened.
    """

    def __init__(self, port: str, baud: int = 115200, timeout: float = 1.0, retries: int = 5):
        if not timeout > 0 or retries < 0:
            raise ValueError(f"timeout must be positive and retries not negative "
                             f"(got {timeout}, {retries})")
        self.port, self.baud, self.timeout, self.retries = port, baud, timeout, retries
        try:
            self._serial = serial.Serial(port, baud, timeout=POLL_SECONDS,
                                         write_timeout=timeout, exclusive=True)
        except (serial.SerialException, ValueError) as problem:
            raise PortError(f"cannot open the instrument's port {port} at {baud} baud: "
                            f"{problem}") from None
        self._buffer = b""
        self._seq = 0
        self._last = "nothing yet"  # for messages: the last command and its reply
        self.resends = 0  # commands resent over the whole session

    def close(self) -> None:
        self._serial.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def command(self, word: str, *args) -> tuple[str, ...]:
        """Send one command and return the values of its ``OK`` reply.

        Raises:
            RefusedError: the instrument answered ``ERR``.
            NoAnswerError, GarbledError: no valid reply after every retry.
            DisconnectedError: the port went away.
        """
        self._seq = self._seq % protocol.MAX_SEQ + 1
        line = protocol.encode(self._seq, word, *args)
        sent = line.decode("ascii").strip()
        heard = _Heard()
        for attempt in range(self.retries + 1):
            if attempt:
                self.resends += 1
            self._write(line, sent)
            deadline = time.monotonic() + self.timeout
            while (raw := self._readline(deadline, sent)) is not None:
                try:
                    reply = protocol.decode(raw)
                except protocol.FrameError as problem:
                    heard.garbled, heard.last_garbled = heard.garbled + 1, (raw, problem)
                    break  # resend: the instrument repeats its reply, not the command
                if reply.seq == protocol.NAK_SEQ:
                    heard.naks += 1
                    break
                if reply.seq != self._seq:
                    continue  # a late answer to an earlier try or command
                if reply.word == "BUSY":
                    deadline = time.monotonic() + float(reply.args[0]) + self.timeout
                    continue
                self._last = f"{sent!r} answered {reply.word} {' '.join(reply.args)}".strip()
                if reply.word == "ERR":
                    code, text = reply.args[0], " ".join(reply.args[1:])
                    raise RefusedError(f"the instrument on {self.port} refused {sent!r}: "
                                       f"{code} {text}", code, text)
                return reply.args
            else:  # the deadline passed
                heard.partial |= bool(self._buffer)
                self._buffer = b""  # a partial line: its terminator was lost
        raise self._failure(sent, heard)

    def _failure(self, sent: str, heard: _Heard) -> InstrumentError:
        where = f"the instrument on {self.port} ({self.baud} baud)"
        tries = f"{self.retries + 1} tries"
        if heard.garbled:
            raw, problem = heard.last_garbled
            return GarbledError(
                f"{where} answered {sent!r} with {heard.garbled} line(s) that do not frame in "
                f"{tries} (last {raw[:60]!r}: {problem}); a wrong baud rate does this (use "
                "the instrument's --baud), as does a very noisy line")
        if heard.naks:
            return GarbledError(
                f"{where} reported {heard.naks} time(s) in {tries} that {sent!r} arrived "
                "damaged: the line to the instrument is noisy")
        what = "only part of a line" if heard.partial else "nothing"
        return NoAnswerError(
            f"{where} answered {sent!r} with {what} in {tries} of {self.timeout:g} s "
            f"(last exchange: {self._last}); is it switched on, and is this its port?")

    def _write(self, line: bytes, sent: str) -> None:
        try:
            self._serial.write(line)
        except serial.SerialTimeoutException:
            raise NoAnswerError(f"the instrument on {self.port} did not take {sent!r} within "
                                f"{self.timeout:g} s (it is not reading its input)") from None
        except OSError as problem:
            raise self._disconnected(sent, problem) from None

    def _readline(self, deadline: float, sent: str) -> bytes | None:
        """The next line (with its terminator), or None at the deadline."""
        while b"\n" not in self._buffer:
            if time.monotonic() >= deadline:
                return None
            try:
                self._buffer += self._serial.read(max(1, self._serial.in_waiting))
            except OSError as problem:  # SerialException is an OSError
                raise self._disconnected(sent, problem) from None
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line + b"\n"

    def _disconnected(self, sent: str, problem) -> DisconnectedError:
        return DisconnectedError(f"lost the instrument on {self.port} while sending {sent!r} "
                                 f"or waiting for its reply ({problem}); last exchange: "
                                 f"{self._last}")

    def identify(self) -> dict:
        """``IDN?``: model, serial, firmware, baud and wavelength_nm."""
        model, serial_number, firmware, baud, wavelength = self.command("IDN?")
        return {"model": model, "serial": serial_number, "firmware": firmware,
                "baud": int(baud), "wavelength_nm": float(wavelength)}

    def limits(self, motor: str) -> tuple[float, float]:
        """``LIMITS?``: a motor's range in degrees."""
        _, low, high = self.command("LIMITS?", motor)
        return float(low), float(high)

    def home(self) -> None:
        """``HOME``: every motor to 0 deg."""
        self.command("HOME")

    def move(self, motor: str, degrees: float) -> float:
        """``MOVE``: one motor to an angle; returns where it stopped (0.01 deg steps)."""
        return float(self.command("MOVE", motor, f"{degrees:.4f}")[1])

    def position(self, motor: str) -> float:
        """``POS?``: where a motor is, in degrees."""
        return float(self.command("POS?", motor)[1])

    def select(self, target: str) -> None:
        """``SELECT``: put the ``SAMPLE`` or the ``REFERENCE`` plate in the beam."""
        self.command("SELECT", target)

    def read(self, count: int, integration_ms: float) -> Reading:
        """``READ``: average ``count`` integrations of ``integration_ms`` each."""
        volts, std, n = self.command("READ", count, f"{integration_ms:g}")
        return Reading(float(volts), float(std), int(n))

    def status(self) -> dict:
        """``STATUS?`` as a dict of strings (``homed``, ``target``, ``A``, ``moves``, ...)."""
        return dict(field.split("=", 1) for field in self.command("STATUS?"))

"""RoboClaw packet-serial protocol: CRC, literal frames, reply parsing, driver retries and errors.

Expected bytes were derived by hand from the protocol description (big-endian
fields; CRC-16/XMODEM over address, command, data) and cross-checked with the
bit-by-bit reference CRC below, which is independent of ``binascii``.
"""

from __future__ import annotations

import sys

import pytest

from trajopt.hardware import protocol as P
from trajopt.hardware.driver import RoboClaw, import_serial
from trajopt.hardware.errors import (
    RoboClawCRCError,
    RoboClawError,
    RoboClawNoAck,
    RoboClawTimeout,
    RoboClawUnmatchedReply,
)


def reference_crc(data: bytes) -> int:
    """Textbook bitwise CRC-16/XMODEM (poly 0x1021, init 0)."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
            crc &= 0xFFFF
    return crc


class ScriptedSerial:
    """Serial stand-in: each write makes the next scripted reply readable."""

    def __init__(self, replies: list[bytes]) -> None:
        self.timeout = 0.01
        self.replies = list(replies)
        self.written: list[bytes] = []
        self.flushes = 0
        self._in = bytearray()

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        if self.replies:
            self._in += self.replies.pop(0)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        out = bytes(self._in[:size])
        del self._in[:size]
        return out

    def reset_input_buffer(self) -> None:
        self.flushes += 1
        self._in.clear()

    def close(self) -> None:
        pass


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# --------------------------------------------------------------------------- CRC
def test_crc_check_value() -> None:
    assert P.crc16(b"123456789") == 0x31C3
    assert reference_crc(b"123456789") == 0x31C3
    assert P.crc16(b"") == 0


@pytest.mark.parametrize("data", [b"\x80\x10", b"\x80\x15", bytes(range(256)), b"\xff" * 33])
def test_crc_matches_reference(data: bytes) -> None:
    assert P.crc16(data) == reference_crc(data)


# --------------------------------------------------------------------------- request frames
FRAMES = [
    (lambda: P.read_frame(0x80, P.Cmd.READ_ENCODER_M1), "80 10 09 a9"),
    (lambda: P.read_frame(0x80, P.Cmd.READ_ENCODER_M2), "80 11 19 88"),
    (lambda: P.reset_encoders_frame(0x80), "80 14 49 2d"),
    (lambda: P.read_frame(0x80, P.Cmd.READ_FIRMWARE), "80 15 59 0c"),
    (lambda: P.set_encoder_frame(0x80, 1, 1000), "80 16 00 00 03 e8 34 8a"),
    (lambda: P.set_encoder_frame(0x80, 2, -1), "80 17 ff ff ff ff 2e 61"),
    (lambda: P.read_frame(0x80, P.Cmd.READ_MAIN_BATTERY), "80 18 88 a1"),
    (lambda: P.duty_frame(0x80, 1, 16384), "80 20 40 00 56 32"),
    (lambda: P.duty_frame(0x81, 2, -32767), "81 21 80 01 11 c3"),
    (lambda: P.speed_frame(0x80, 1, -1000), "80 23 ff ff fc 18 73 13"),
    (lambda: P.speed_frame(0x80, 2, 4500), "80 24 00 00 11 94 a6 ed"),
    # D=2.0*1024, P=1.0*1024, I=0.25*1024 (wire order D, P, I), MaxI 100, deadzone 5, min -1000, max 1000
    (lambda: P.set_position_pid_frame(0x80, 1, p=1.0, i=0.25, d=2.0, max_i=100, deadzone=5, min_pos=-1000,
                                      max_pos=1000),
     "80 3d 00 00 08 00 00 00 04 00 00 00 01 00 00 00 00 64 00 00 00 05 ff ff fc 18 00 00 03 e8 ce 19"),
    (lambda: P.read_frame(0x80, P.Cmd.READ_POSITION_PID_M2), "80 40 53 5c"),
    (lambda: P.speed_accel_decel_position_frame(0x80, 1, 30000, 4500, 30000, -200, buffer=False),
     "80 41 00 00 75 30 00 00 11 94 00 00 75 30 ff ff ff 38 01 ce 5d"),
    (lambda: P.speed_accel_decel_position_frame(0x82, 2, 1, 2, 3, 4, buffer=True),
     "82 42 00 00 00 01 00 00 00 02 00 00 00 03 00 00 00 04 00 92 c5"),
    (lambda: P.read_frame(0x87, P.Cmd.READ_STATUS), "87 5a 79 b0"),
]


@pytest.mark.parametrize("build, expected", FRAMES)
def test_frames_literal(build, expected: str) -> None:
    frame = build()
    assert frame == h(expected)
    assert reference_crc(frame[:-2]) == int.from_bytes(frame[-2:], "big")
    assert len(frame) == 4 + P.REQUEST_DATA_LEN[frame[1]]


@pytest.mark.parametrize("call, fragment", [
    (lambda: P.build_frame(0x7F, 16), "0x7f"),
    (lambda: P.build_frame(0x88, 16), "0x88"),
    (lambda: P.duty_frame(0x80, 1, 40000), "40000"),
    (lambda: P.duty_frame(0x80, 1, -32768), "-32768"),
    (lambda: P.duty_frame(0x80, 3, 0), "3"),
    (lambda: P.duty_frame(0x80, 1, 1.5), "1.5"),
    (lambda: P.speed_frame(0x80, 1, 2**31), str(2**31)),
    (lambda: P.set_encoder_frame(0x80, 1, -(2**31) - 1), str(-(2**31) - 1)),
    (lambda: P.speed_accel_decel_position_frame(0x80, 1, 1, -5, 1, 0, False), "-5"),
    (lambda: P.set_position_pid_frame(0x80, 1, -1.0, 0, 0, 0, 0, 0, 0), "-1024"),
])
def test_argument_validation_names_value(call, fragment: str) -> None:
    with pytest.raises(ValueError, match=fragment.replace("+", r"\+")):
        call()


# --------------------------------------------------------------------------- reply parsing
def test_parse_replies() -> None:
    assert P.parse_encoder(h("ff ff ff fe 02")) == (-2, 2)
    assert P.parse_battery(h("00 7b")) == pytest.approx(12.3)
    assert P.parse_status(h("12 34 56 78")) == 0x12345678
    pid = P.parse_position_pid(h("00 00 04 00 00 00 01 00 00 00 08 00 00 00 00 64 00 00 00 05 ff ff fc 18 00 00 03 e8"))
    assert pid == (1.0, 0.25, 2.0, 100, 5, -1000, 1000)
    # reply CRC covers the request's address and command bytes, then the reply data
    assert P.reply_crc(0x80, 16, h("ff ff ff fe 02")) == h("7f 9e")
    assert P.reply_crc(0x80, 24, h("00 7b")) == h("f8 06")


@pytest.mark.parametrize("text, version", [
    ("USB Roboclaw 2x7a v4.1.34", (4, 1, 34)),
    ("Roboclaw 2x15a v4.2.8\n", (4, 2, 8)),
    ("USB Roboclaw 2x7a v3.1.10", (3, 1, 10)),
    ("MCP266 v1.0.0", None),
    ("", None),
    ("USB Roboclaw 2x7a", None),
])
def test_firmware_version(text: str, version: tuple[int, int, int] | None) -> None:
    assert P.parse_firmware_version(text) == version


# --------------------------------------------------------------------------- driver on a scripted port
FIRMWARE_REPLY = b"USB Roboclaw 2x7a v4.1.34\n\x00" + h("0b f6")


def test_driver_reads_parse_literal_replies() -> None:
    ser = ScriptedSerial([h("ff ff ff fe 02 7f 9e"), h("00 7b f8 06"), FIRMWARE_REPLY])
    rc = RoboClaw(ser, 0x80, timeout=0.01, retries=0)
    assert rc.read_encoder(1) == (-2, 2)
    assert rc.read_main_battery_voltage() == pytest.approx(12.3)
    assert rc.read_firmware() == "USB Roboclaw 2x7a v4.1.34"
    assert ser.written == [h("80 10 09 a9"), h("80 18 88 a1"), h("80 15 59 0c")]


def test_driver_write_sends_frame_and_accepts_ack() -> None:
    ser = ScriptedSerial([b"\xff"] * 4)
    rc = RoboClaw(ser, 0x80, timeout=0.01, retries=0)
    rc.duty(1, 16384)
    rc.speed_accel_decel_position(1, 30000, 4500, 30000, -200, buffer=False)
    rc.stop_all()
    assert ser.written == [h("80 20 40 00 56 32"), h("80 41 00 00 75 30 00 00 11 94 00 00 75 30 ff ff ff 38 01 ce 5d"),
                           h("80 20 00 00 5b fe"), h("80 21 00 00 6c ce")]


BATTERY_REPLY = h("00 7b f8 06")  # 12.3 V


def test_driver_retry_of_a_write_probes_the_line_first() -> None:
    """The first ACK may still arrive late: before re-sending, a read proves nothing is owed any more."""
    ser = ScriptedSerial([b"", BATTERY_REPLY, b"\xff"])
    rc = RoboClaw(ser, 0x80, timeout=0.01, retries=2)
    rc.duty(1, 0)
    assert ser.written == [h("80 20 00 00 5b fe"), h("80 18 88 a1"), h("80 20 00 00 5b fe")]
    assert ser.flushes == 3  # stale input drained before every request
    assert rc.line.in_sync()


def test_driver_write_whose_probe_fails_is_sent_but_not_acknowledged() -> None:
    """A stop must go out even on a doubtful line, but a 0xFF then proves nothing."""
    ser = ScriptedSerial([b"", b"", b"\xff"])
    rc = RoboClaw(ser, 0x80, timeout=0.01, retries=0)
    with pytest.raises(RoboClawTimeout):
        rc.duty(1, 16384)  # its ACK may still arrive late
    with pytest.raises(RoboClawUnmatchedReply, match="may be a late reply"):
        rc.duty(1, 0)  # the probe is not answered: the 0xff that follows may be the late one
    assert ser.written == [h("80 20 40 00 56 32"), h("80 18 88 a1"), h("80 20 00 00 5b fe")]
    assert not rc.line.in_sync()
    with pytest.raises(RoboClawTimeout) as info:
        RoboClaw(ScriptedSerial([]), 0x80, timeout=0.01, retries=1).duty(1, 0)
    assert info.value.attempts == 2 and info.value.command == 32  # the root cause, not the failed probe


class PeekSerial(ScriptedSerial):
    """ScriptedSerial that also reports how many bytes wait (like pyserial's ``in_waiting``)."""

    @property
    def in_waiting(self) -> int:
        return len(self._in)


def test_stale_bytes_are_drained_before_a_request() -> None:
    """A stale 0xFF already waiting is not the acknowledgement of the next write."""
    ser = PeekSerial([b""])
    ser._in += b"\xff"  # a late ACK of some earlier write
    rc = RoboClaw(ser, 0x80, timeout=0.01, retries=0)
    with pytest.raises(RoboClawError):
        rc.duty(1, 0)
    assert rc.line.stray_bytes == 1


def test_bytes_beyond_the_reply_make_it_unmatched() -> None:
    """Two 0xFF for one write: one of them belongs to another request, so neither proves this one."""
    ser = PeekSerial([b"\xff\xff"])
    with pytest.raises(RoboClawUnmatchedReply, match="1 byte"):
        RoboClaw(ser, 0x80, timeout=0.01, retries=0).duty(1, 0)
    ser = PeekSerial([h("ff ff ff fe 02 7f 9e 00")])
    with pytest.raises(RoboClawUnmatchedReply):
        RoboClaw(ser, 0x80, timeout=0.01, retries=0).read_encoder(1)


def test_driver_timeout_names_command_address_and_bytes() -> None:
    ser = ScriptedSerial([h("ff ff"), h("ff ff")])  # 2 of the 7 expected bytes, twice
    with pytest.raises(RoboClawTimeout) as info:
        RoboClaw(ser, 0x81, timeout=0.01, retries=1).read_encoder(2)
    err = info.value
    assert (err.address, err.command, err.attempts, err.received) == (0x81, 17, 2, h("ff ff"))
    text = str(err)
    for fragment in ("0x81", "17", "READ_ENCODER_M2", "ff ff", "2 attempts"):
        assert fragment in text


def test_driver_crc_error_retried_then_ok() -> None:
    ser = ScriptedSerial([h("ff ff ff fe 02 7f 9f"), BATTERY_REPLY, h("ff ff ff fe 02 7f 9e")])
    assert RoboClaw(ser, 0x80, timeout=0.01, retries=1).read_encoder(1).count == -2
    assert ser.written[1] == h("80 18 88 a1")  # probe: a late copy of the encoder reply cannot pass for it
    ser = ScriptedSerial([h("ff ff ff fe 02 7f 9f")])
    with pytest.raises(RoboClawCRCError, match="7f 9f"):
        RoboClaw(ser, 0x80, timeout=0.01, retries=0).read_encoder(1)


def test_driver_no_ack() -> None:
    with pytest.raises(RoboClawNoAck, match="DUTY_M1") as info:
        RoboClaw(ScriptedSerial([b"\x00"]), 0x80, timeout=0.01, retries=0).duty(1, 0)
    assert info.value.received == b"\x00"
    assert isinstance(info.value, RoboClawError)


def test_driver_validates_arguments() -> None:
    with pytest.raises(ValueError, match="0x7f"):
        RoboClaw(ScriptedSerial([]), 0x7F)
    rc = RoboClaw(ScriptedSerial([]), 0x80)
    with pytest.raises(ValueError, match="40000"):
        rc.duty(1, 40000)
    with pytest.raises(ValueError, match="channel"):
        rc.read_encoder(0)


def test_loop_url_echo_is_not_an_ack() -> None:
    """``loop://`` echoes the request: a write sees 0x80 instead of 0xFF, a read times out."""
    pytest.importorskip("serial")
    with RoboClaw("loop://", 0x80, timeout=0.02, retries=0) as rc:
        with pytest.raises(RoboClawNoAck) as info:
            rc.duty(1, 0)
        assert info.value.received == b"\x80"
        rc.serial.reset_input_buffer()
        with pytest.raises(RoboClawTimeout) as info2:
            rc.read_encoder(1)
        assert info2.value.received == h("80 10 09 a9")


def test_missing_pyserial_message(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "serial", None)
    with pytest.raises(ImportError, match=r"pip install soft-envs\[hardware\]"):
        import_serial()
    with pytest.raises(ImportError, match="soft-envs"):
        RoboClaw("loop://")

"""Driver against the RoboClaw emulator over a real pty (pyserial), plus the emulator's motor model."""

from __future__ import annotations

import time
from typing import Callable, Iterator

import pytest

pytest.importorskip("serial")

from trajopt.hardware import protocol as P  # noqa: E402
from trajopt.hardware._motion import ChannelModel, Move  # noqa: E402
from trajopt.hardware.driver import RoboClaw  # noqa: E402
from trajopt.hardware.emulator import RoboClawEmulator  # noqa: E402
from trajopt.hardware.errors import (  # noqa: E402
    RoboClawConnectionError,
    RoboClawCRCError,
    RoboClawNoAck,
    RoboClawTimeout,
)

TIMEOUT = 0.25  # s per reply: generous (a loaded machine), yet each wait on an unanswered request costs one


def wait_for(cond: Callable[[], bool], timeout: float = 60.0) -> bool:
    """Poll ``cond`` until true (the deadline is a safety net, not a timing assertion)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.005)
    return cond()


@pytest.fixture
def emu() -> Iterator[RoboClawEmulator]:
    with RoboClawEmulator(addresses=(0x80, 0x81)) as e:
        yield e


@pytest.fixture
def rc(emu: RoboClawEmulator) -> Iterator[RoboClaw]:
    with RoboClaw(emu.port, 0x80, timeout=TIMEOUT, retries=2) as driver:
        yield driver


# --------------------------------------------------------------------------- round trips
def test_read_commands_round_trip(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.set_battery_voltage(11.7, 0x80)
    emu.set_status(0x12345678, 0x80)
    assert rc.read_firmware() == "USB Roboclaw 2x7a v4.1.34"
    assert rc.read_main_battery_voltage() == pytest.approx(11.7)
    assert rc.read_status() == 0x12345678
    assert rc.read_encoder(1) == (0, 0)
    assert rc.read_encoder(2) == (0, 0)


def test_encoder_set_and_reset(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    rc.set_encoder(1, 1000)
    rc.set_encoder(2, -123456)
    assert rc.read_encoder(1).count == 1000
    assert rc.read_encoder(2).count == -123456
    assert emu.counts(0x80) == (1000, -123456)
    assert emu.counts(0x81) == (0, 0)  # other controller untouched
    rc.reset_encoders()
    assert emu.counts(0x80) == (0, 0)


def test_position_pid_round_trip(rc: RoboClaw) -> None:
    rc.set_position_pid(2, p=1.5, i=0.25, d=10.0, max_i=100, deadzone=5, min_pos=-5000, max_pos=5000)
    assert rc.read_position_pid(2) == (1.5, 0.25, 10.0, 100, 5, -5000, 5000)
    assert rc.read_position_pid(1) == (0.0, 0.0, 0.0, 0, 0, 0, 0)


def test_duty_speed_and_stop(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    rc.duty(1, 16384)
    rc.speed(2, -2000)
    snap = emu.snapshot(0x80)
    assert snap.duties == (16384, 0) and snap.speeds == (0, -2000) and snap.modes == ("duty", "speed")
    assert wait_for(lambda: emu.counts(0x80)[0] > 10 and emu.counts(0x80)[1] < -10)
    assert rc.read_encoder(2).status & 0x02  # direction bit: backwards
    rc.stop_all()
    snap = emu.snapshot(0x80)
    assert snap.modes == ("idle", "idle") and snap.velocities == (0.0, 0.0)
    assert emu.commands(0x80)[-2:] == [P.Cmd.DUTY_M1, P.Cmd.DUTY_M2]


def test_position_move_and_queue(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    rc.speed_accel_decel_position(1, accel=50000, speed=5000, decel=50000, position=300, buffer=False)
    rc.speed_accel_decel_position(1, accel=50000, speed=5000, decel=50000, position=-100, buffer=True)
    snap = emu.snapshot(0x80)
    assert snap.targets[0] == 300 and snap.queued == (1, 0)
    assert wait_for(lambda: emu.snapshot(0x80).targets[0] == -100)
    assert wait_for(lambda: rc.read_encoder(1).count == -100)
    # immediate flag clears the queue
    rc.speed_accel_decel_position(2, 50000, 5000, 50000, 1000, buffer=False)
    rc.speed_accel_decel_position(2, 50000, 5000, 50000, 2000, buffer=True)
    rc.speed_accel_decel_position(2, 50000, 5000, 50000, 50, buffer=False)
    assert emu.snapshot(0x80).queued == (0, 0)
    assert wait_for(lambda: emu.counts(0x80)[1] == 50)


def test_two_addresses_on_one_bus(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    other = rc.at_address(0x81)
    other.set_encoder(1, 77)
    assert other.read_encoder(1).count == 77
    assert rc.read_encoder(1).count == 0
    with pytest.raises(RoboClawTimeout):  # nobody answers 0x82
        rc.at_address(0x82).read_encoder(1)


# --------------------------------------------------------------------------- framing rules
def test_bad_crc_request_dropped_silently(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    ser = rc.serial
    ser.write(bytes.fromhex("80 18 88 a2"))  # battery request, CRC off by one
    time.sleep(0.05)
    assert ser.read(16) == b""
    assert emu.dropped_packets >= 1
    assert emu.commands() == []
    assert rc.read_main_battery_voltage() == pytest.approx(12.0)


def test_partial_packet_dropped_after_silence(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    ser = rc.serial
    ser.write(bytes.fromhex("80 10"))  # first half of "read encoder M1"
    time.sleep(0.05)  # > 10 ms of silence: the emulator forgets it
    ser.write(bytes.fromhex("80 18 88 a1"))  # complete battery request
    reply = ser.read(4)
    assert reply == bytes.fromhex("00 78") + P.reply_crc(0x80, 24, bytes.fromhex("00 78"))
    assert emu.commands() == [P.Cmd.READ_MAIN_BATTERY]


# --------------------------------------------------------------------------- faults
def test_dropped_replies_are_retried(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.inject_no_reply(2)
    assert rc.read_encoder(1).count == 0
    # lost request; lost probe (the read is then not re-sent: a late reply could pass for it);
    # a probe with a command owed by neither; the read
    assert [(p.command, p.answered) for p in emu.received] == [(16, False), (24, False), (17, True), (16, True)]
    assert rc.line.in_sync()


def test_no_reply_forever_raises_timeout(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.hang()
    with pytest.raises(RoboClawTimeout) as info:
        rc.duty(1, 0)
    assert info.value.attempts == 3 and info.value.address == 0x80 and info.value.command == 32
    # a write goes out on every attempt, each retry after a (failed) probe of the line
    assert emu.commands() == [32, 24, 32, 16, 32]
    assert not any(p.executed for p in emu.received)
    emu.clear_faults()
    rc.duty(1, 0)
    assert rc.line.in_sync()


def test_lost_late_and_partial_replies_are_retried(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.inject_lost_reply(1, command=P.Cmd.READ_MAIN_BATTERY)
    assert rc.read_main_battery_voltage() == pytest.approx(12.0)
    emu.inject_partial_reply(3, command=P.Cmd.READ_ENCODER_M1)
    rc.set_encoder(1, 42)
    assert rc.read_encoder(1).count == 42
    emu.inject_late_reply(None, command=P.Cmd.DUTY_M2)  # leaves with the next request: after the timeout
    rc.duty(2, 0)  # late ACK of attempt 1 arrives with the probe: the probe fails, then a clean retry
    assert rc.read_encoder(2).count == 0
    assert rc.line.in_sync()
    assert [p.executed for p in emu.received].count(False) == 0  # these faults lose replies, not requests


def test_late_reply_keeps_reply_order(emu: RoboClawEmulator) -> None:
    ser = __import__("serial").Serial(emu.port, timeout=10.0)  # read(5) returns once 5 bytes are in
    emu.inject_late_reply(0.05, command=P.Cmd.READ_MAIN_BATTERY)
    ser.write(P.read_frame(0x80, P.Cmd.READ_MAIN_BATTERY) + P.duty_frame(0x80, 1, 0))
    assert ser.read(5) == bytes.fromhex("00 78") + P.reply_crc(0x80, 24, bytes.fromhex("00 78")) + b"\xff"
    ser.close()


def test_jammed_channel_does_not_move(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.jam(1, 0x80)
    rc.speed_accel_decel_position(1, 50000, 5000, 50000, 500, buffer=False)
    rc.speed_accel_decel_position(2, 50000, 5000, 50000, 500, buffer=False)
    assert wait_for(lambda: emu.counts(0x80)[1] == 500)
    assert emu.counts(0x80)[0] == 0 and emu.snapshot(0x80).jammed == (True, False)
    emu.jam(1, 0x80, jammed=False)
    assert wait_for(lambda: emu.counts(0x80)[0] == 500)


def test_bad_crc_reply(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.inject_bad_crc(None)
    with pytest.raises(RoboClawCRCError, match="READ_MAIN_BATTERY") as info:
        rc.read_main_battery_voltage()
    assert len(info.value.received) == 4
    emu.clear_faults()
    emu.inject_bad_crc(1)
    assert rc.read_firmware().startswith("USB Roboclaw")  # one bad reply, retry succeeds


def test_bad_ack(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.inject_bad_ack(None)
    with pytest.raises(RoboClawNoAck):
        rc.reset_encoders()


def test_disconnect(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    assert rc.read_encoder(1).count == 0
    emu.disconnect()
    assert not emu.connected
    t0 = time.monotonic()
    with pytest.raises(RoboClawConnectionError):
        rc.read_encoder(1)
    assert time.monotonic() - t0 < 1.0  # not retried: fails fast rather than after all timeouts


def test_disconnect_after_packets(emu: RoboClawEmulator, rc: RoboClaw) -> None:
    emu.disconnect_after(2)
    rc.duty(1, 0)
    with pytest.raises(RoboClawConnectionError):
        rc.duty(2, 0)
    assert [p.answered for p in emu.received] == [True, False]


# --------------------------------------------------------------------------- motor model (no threads)
def run(ch: ChannelModel, seconds: float, h: float = 0.0005) -> list[tuple[float, float]]:
    trace = []
    for _ in range(round(seconds / h)):
        ch.advance(h)
        trace.append((ch.pos, ch.vel))
    return trace


def test_trapezoid_respects_limits_and_arrives() -> None:
    ch = ChannelModel()
    ch.command_move(Move(accel=20000, speed=3000, decel=10000, position=2000), immediate=True)
    trace = run(ch, 1.5)
    vels = [v for _, v in trace]
    assert ch.pos == 2000.0 and ch.vel == 0.0
    assert max(vels) <= 3000.0 + 1e-9
    dv = [b - a for a, b in zip(vels, vels[1:])]
    assert max(dv) <= 20000 * 0.0005 + 1e-6  # speeding up at most accel
    assert min(dv[:-1]) >= -10000 * 0.0005 - 1e-6  # slowing down at most decel (last step: arrival)


def test_queued_move_and_reverse() -> None:
    ch = ChannelModel()
    ch.command_move(Move(0, 2000, 0, 100), immediate=True)  # accel 0 = unlimited
    ch.command_move(Move(0, 2000, 0, -100), immediate=False)
    run(ch, 0.2)
    assert ch.pos == -100.0
    ch.command_move(Move(1000, 0, 1000, 500), immediate=True)  # speed 0 holds still
    run(ch, 0.1)
    assert ch.pos == -100.0


def test_duty_model() -> None:
    ch = ChannelModel(no_load_speed=6000.0)
    ch.set_duty(-32767)
    run(ch, 0.1, h=0.001)
    assert ch.pos == pytest.approx(-600.0)
    ch.set_duty(0)
    assert ch.mode == "idle" and ch.vel == 0.0

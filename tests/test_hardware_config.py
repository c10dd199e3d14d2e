"""Hardware TOML: shipped examples, validation errors naming file and field, unit conversion."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from trajopt.hardware.config import (
    DEFAULT_COUNTS_PER_REV,
    EXAMPLE_PUPPY,
    EXAMPLE_TRIPOD,
    MotorConfig,
    load_hardware_config,
)

GOOD_MOTOR = """
[motors.left]
port = "/dev/ttyACM0"
address = 0x80
channel = 1
spool_radius = 0.005
max_speed = 4000
max_accel = 30000
"""


def test_examples_load() -> None:
    puppy = load_hardware_config(EXAMPLE_PUPPY)
    assert len(puppy.motors) == 8 and puppy.robot == "puppy"
    assert [a for _, a in puppy.controllers()] == [0x80, 0x81, 0x82, 0x83]
    assert {m.port for m in puppy.motors.values()} == {"/dev/ttyACM0"}
    assert puppy.min_battery_voltage == 10.5
    tripod = load_hardware_config(EXAMPLE_TRIPOD)
    assert list(tripod.motors) == ["front", "back"]
    assert tripod.controllers() == [("/dev/ttyACM0", 0x80)]
    assert tripod.motors["front"].counts_per_rev == pytest.approx(3575.04)
    over = tripod.with_port_override("/dev/pts/9")
    assert {m.port for m in over.motors.values()} == {"/dev/pts/9"}


def test_defaults(tmp_path: Path) -> None:
    path = tmp_path / "hw.toml"
    path.write_text(GOOD_MOTOR)
    cfg = load_hardware_config(path)
    m = cfg.motors["left"]
    assert m.counts_per_rev == DEFAULT_COUNTS_PER_REV and m.direction == 1 and m.u_min is None
    assert (cfg.baudrate, cfg.timeout, cfg.retries, cfg.min_battery_voltage) == (115200, 0.1, 2, 0.0)
    assert (cfg.max_tracking_error, cfg.max_tracking_error_time, cfg.allow_untested_firmware) == (0.002, 0.3, False)


def test_conversion() -> None:
    m = MotorConfig("m", "p", 0x80, 1, spool_radius=0.01, max_speed=1, max_accel=1)
    one_turn = 2 * math.pi * 0.01
    assert m.to_counts(one_turn) == round(DEFAULT_COUNTS_PER_REV) == 3575
    assert m.to_counts(0.0) == 0
    flipped = MotorConfig("m", "p", 0x80, 1, 0.01, 1, 1, counts_per_rev=1000.0, direction=-1)
    np.testing.assert_array_equal(flipped.to_counts(np.array([0.0, one_turn / 2, -one_turn])), [0, -500, 1000])
    assert flipped.to_length(-500) == pytest.approx(one_turn / 2)


BAD = [
    # (TOML text, field expected in the message)
    (GOOD_MOTOR.replace('port = "/dev/ttyACM0"\n', ""), "motors.left.port"),
    (GOOD_MOTOR.replace("channel = 1", "channel = 1\ncolour = 'red'"), "motors.left.colour"),
    (GOOD_MOTOR.replace("address = 0x80", 'address = "0x80"'), "motors.left.address"),
    (GOOD_MOTOR.replace("address = 0x80", "address = 0x90"), "motors.left.address"),
    (GOOD_MOTOR.replace("channel = 1", "channel = 3"), "motors.left.channel"),
    (GOOD_MOTOR.replace("channel = 1", "channel = true"), "motors.left.channel"),
    (GOOD_MOTOR.replace("spool_radius = 0.005", "spool_radius = -0.005"), "motors.left.spool_radius"),
    (GOOD_MOTOR.replace("spool_radius = 0.005", "spool_radius = nan"), "motors.left.spool_radius"),
    (GOOD_MOTOR.replace("max_speed = 4000", "max_speed = 0"), "motors.left.max_speed"),
    (GOOD_MOTOR.replace("max_accel = 30000", "max_accel = [1]"), "motors.left.max_accel"),
    (GOOD_MOTOR + "direction = 0\n", "motors.left.direction"),
    (GOOD_MOTOR + "direction = 2\n", "motors.left.direction"),
    (GOOD_MOTOR + "counts_per_rev = 0\n", "motors.left.counts_per_rev"),
    (GOOD_MOTOR + "u_min = 0.02\nu_max = 0.01\n", "motors.left.u_max"),
    (GOOD_MOTOR + "u_min = 'low'\n", "motors.left.u_min"),
    (GOOD_MOTOR + GOOD_MOTOR.replace("motors.left", "motors.right"), "motors.right"),  # same wiring twice
    ("[settings]\ntimeout = 'fast'\n" + GOOD_MOTOR, "settings.timeout"),
    ("[settings]\nbaud = 9600\n" + GOOD_MOTOR, "settings.baud"),
    ("[settings]\nmin_battery_voltage = -1\n" + GOOD_MOTOR, "settings.min_battery_voltage"),
    ("[settings]\nretries = 1.5\n" + GOOD_MOTOR, "settings.retries"),
    ("[settings]\nmax_tracking_error = 0\n" + GOOD_MOTOR, "settings.max_tracking_error"),
    ("[settings]\nmax_tracking_error = inf\n" + GOOD_MOTOR, "settings.max_tracking_error"),
    ("[settings]\nmax_tracking_error_time = -0.1\n" + GOOD_MOTOR, "settings.max_tracking_error_time"),
    ("[settings]\nallow_untested_firmware = 1\n" + GOOD_MOTOR, "settings.allow_untested_firmware"),
    ("speed = 3\n" + GOOD_MOTOR, "speed"),
    ("robot = 'x'\n", "motors"),
    ("motors = 5\n", "motors"),
    ("[motors]\nleft = 5\n", "motors.left"),
    ("[motors.left\nport = 1", "invalid TOML"),
]


@pytest.mark.parametrize("text, field", BAD)
def test_bad_files_name_file_and_field(tmp_path: Path, text: str, field: str) -> None:
    path = tmp_path / "broken_hw.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        load_hardware_config(path)
    message = str(info.value)
    assert str(path) in message
    assert field in message


def test_port_override_collision_is_reported(tmp_path: Path) -> None:
    path = tmp_path / "two_ports.toml"
    path.write_text(GOOD_MOTOR + GOOD_MOTOR.replace("motors.left", "motors.right").replace("ttyACM0", "ttyACM1"))
    cfg = load_hardware_config(path)
    with pytest.raises(ValueError, match="motors.right"):
        cfg.with_port_override("/dev/ttyUSB0")


def test_non_utf8_file_names_file_byte_and_line(tmp_path: Path) -> None:
    text = EXAMPLE_TRIPOD.read_bytes()
    at = text.index(b"[settings]")  # a Latin-1 comment: "# réglages"
    bad = text[:at] + "# r\xe9glages\n".encode("latin-1") + text[at:]
    path = tmp_path / "hw.toml"
    path.write_bytes(bad)
    offset, line = at + 3, text.count(b"\n", 0, at) + 1
    with pytest.raises(ValueError) as info:
        load_hardware_config(path)
    assert str(info.value) == (f"{path}: not UTF-8 text: byte 0xe9 at offset {offset} (line {line}); "
                               "save the file as UTF-8")


def test_non_utf8_file_through_the_cli_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                                           ) -> None:
    import argparse

    from trajopt.cli.play import add_play_parser, run_play
    from trajopt.results.result import Result

    u = np.zeros((5, 2))
    result = Result(robot="tripod", task="walk", motor_names=["front", "back"], dt=0.033, z=np.zeros(1), u=u,
                    u_post=u, target=np.zeros((0, 2)), com=np.zeros((0, 3))).save(tmp_path / "gait.npz")
    path = tmp_path / "hw.toml"
    path.write_bytes(b"\xff\xfe" + EXAMPLE_TRIPOD.read_bytes())  # saved as UTF-16 by an editor, say
    parser = argparse.ArgumentParser(prog="trajopt")
    add_play_parser(parser.add_subparsers(dest="command", required=True))
    code = run_play(parser.parse_args(["play", str(result), "--hardware", str(path)]))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert f"{path}: not UTF-8 text: byte 0xff at offset 0 (line 1)" in err

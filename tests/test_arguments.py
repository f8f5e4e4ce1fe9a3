"""The argparse types every command shares (simbot/arguments.py): what each accepts and the one line it
gives for what it refuses, through a real parser's exit code 2."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

import pytest

from simbot.arguments import image_size, number, whole


def _parsed(kind: Callable[[str], object], text: str, capsys: pytest.CaptureFixture[str]) -> tuple[object, str]:
    """The value `--x text` gives, or None and argparse's error line after its exit 2."""
    parser = argparse.ArgumentParser(prog="prog")
    parser.add_argument("--x", type=kind)
    try:
        return parser.parse_args([f"--x={text}"]).x, ""
    except SystemExit as exit_:
        assert exit_.code == 2
        return None, capsys.readouterr().err.strip().splitlines()[-1]


@pytest.mark.parametrize(("text", "value"), [("0.05", 0.05), ("3", 3.0), ("1e3", 1000.0)])
def test_a_positive_number_is_taken(text: str, value: float, capsys: pytest.CaptureFixture[str]) -> None:
    assert _parsed(number(float, unit="m"), text, capsys) == (value, "")


@pytest.mark.parametrize("text", ["0", "-1", "nan", "inf", "-inf"])
def test_zero_negative_and_non_finite_are_refused_naming_the_option(
    text: str, capsys: pytest.CaptureFixture[str]
) -> None:
    value, error = _parsed(number(float, unit="Hz"), text, capsys)
    assert value is None
    assert error == f"prog: error: argument --x: expected a finite number > 0 Hz, got {text!r}"


def test_at_least_zero_takes_zero_and_a_word_is_not_a_number(capsys: pytest.CaptureFixture[str]) -> None:
    assert _parsed(number(int, at_least_zero=True), "0", capsys) == (0, "")
    _, error = _parsed(number(float, unit="m"), "far", capsys)
    assert error == "prog: error: argument --x: expected a number of m, got 'far'"
    assert math.isclose(number(float)("2.5"), 2.5)


@pytest.mark.parametrize(("text", "value"), [("0", 0), ("65535", 65535), ("8765", 8765)])
def test_a_whole_number_within_bounds_is_taken(text: str, value: int, capsys: pytest.CaptureFixture[str]) -> None:
    assert _parsed(whole(0, 65535), text, capsys) == (value, "")


@pytest.mark.parametrize("text", ["-1", "65536", "1.5", "port"])
def test_a_whole_number_out_of_bounds_or_not_whole_is_refused(text: str, capsys: pytest.CaptureFixture[str]) -> None:
    value, error = _parsed(whole(0, 65535), text, capsys)
    assert value is None
    assert error == f"prog: error: argument --x: expected a whole number from 0 to 65535, got {text!r}"


def test_without_an_upper_bound_only_the_lower_one_holds(capsys: pytest.CaptureFixture[str]) -> None:
    assert _parsed(whole(), "1000000", capsys) == (1000000, "")
    _, error = _parsed(whole(), "0", capsys)
    assert error == "prog: error: argument --x: expected a whole number ≥ 1, got '0'"


@pytest.mark.parametrize(("text", "value"), [("320x240", (320, 240)), ("8192X1", (8192, 1))])
def test_an_image_size_is_taken(text: str, value: tuple[int, int], capsys: pytest.CaptureFixture[str]) -> None:
    assert _parsed(image_size, text, capsys) == (value, "")


@pytest.mark.parametrize(
    ("text", "why"),
    [("0x240", "width and height must be 1..8192"), ("320", "expected WxH such as 320x240"), ("8193x2", "1..8192")],
)
def test_an_image_size_out_of_bounds_or_malformed_is_refused(
    text: str, why: str, capsys: pytest.CaptureFixture[str]
) -> None:
    value, error = _parsed(image_size, text, capsys)
    assert value is None and error.startswith("prog: error: argument --x: ") and why in error and repr(text) in error

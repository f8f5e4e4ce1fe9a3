"""The errors of a user's bad description: a file that cannot be read (`DescriptionError`, naming
the file, element and line), and a system's `<plugin>` or `<sensor>` parameters that cannot be used
(`SystemConfigError`, naming the plugin or sensor and the element)."""

from __future__ import annotations

from pathlib import Path


class DescriptionError(Exception):
    """A description that cannot be read; str() is the one line a CLI prints."""

    def __init__(
        self,
        file: Path | str | None,
        message: str,
        element: str | None = None,
        line: int | None = None,
    ) -> None:
        self.file = str(file) if file is not None else "<input>"
        self.message = " ".join(message.split())  # one line, whatever the cause's own text
        self.element = element
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        where = self.file if self.line is None else f"{self.file}:{self.line}"
        what = f" <{self.element}>" if self.element else ""
        return f"{where}:{what} {self.message}"


class SystemConfigError(ValueError):
    """A system's SDF parameters are unusable; the message names the plugin and the parameter. The
    world leaves that system out with the message as one error line, and runs (simbot/sim/loop/world.py);
    `simbot describe` lists it (simbot/sim/loop/sdf_systems.py)."""

"""The one error a user's bad description file raises: it names the file, element and line."""

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

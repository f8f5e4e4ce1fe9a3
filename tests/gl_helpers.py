"""Whether the OpenGL renderer can run here: tests of `gl` skip with this reason where no EGL context opens."""

from __future__ import annotations


def _why_no_egl() -> str | None:
    try:
        import moderngl

        moderngl.create_context(standalone=True, backend="egl", require=330).release()
    except Exception as exc:  # noqa: BLE001 - any failure means no GL here
        return f"no OpenGL 3.3 EGL context opens on this machine ({exc})"
    return None


NO_EGL = _why_no_egl()
"""None where an EGL context opens; else the reason, for pytest.skip."""

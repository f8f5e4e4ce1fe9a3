"""Whether the OpenGL renderer can run here (tests of `gl` skip with this reason where no EGL context
opens), and the bodies the rendering tests draw."""

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


INERTIA = '<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/>'


def box_urdf(
    size: tuple[float, float, float], rgba: tuple[float, ...], com: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> str:
    """A one-link box; `com` puts its centre of mass beside the visual."""
    return f"""<robot name="box"><link name="box">
      <inertial><origin xyz="{com[0]} {com[1]} {com[2]}"/><mass value="1"/>{INERTIA}</inertial>
      <visual><geometry><box size="{size[0]} {size[1]} {size[2]}"/></geometry>
        <material name="c"><color rgba="{" ".join(map(str, rgba))}"/></material></visual>
    </link></robot>"""

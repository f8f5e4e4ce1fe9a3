"""Camera rendering: worker processes (`pool.py`, `worker.py`) with their own copy of the scene
(`scene.py`), drawn by OpenGL (`gl.py`, its shaders `gl_shaders.py` and shadows `gl_shadow.py`; the bodies' pieces from `visuals.py`) or TinyRenderer (`tiny.py`),
finished into a camera's named outputs (their kinds: `kinds.py`; the built-in colour, mono, depth,
points, labels (packed: `label_bits.py`) and temperature: `outputs.py`); what crosses the process boundary is in `specs.py`, the messages that
carry it in `pipe.py`."""

from simbot.sim.render.kinds import OutputKind, output_kinds
from simbot.sim.render.pool import PoolPlan, RenderPool, plan_pool
from simbot.sim.render.specs import Annotation, BodyState, CameraSpec, Frame, Light, LightSource, SceneBody
from simbot.sim.render.worker import RENDERERS

__all__ = [
    "RENDERERS",
    "Annotation",
    "BodyState",
    "CameraSpec",
    "Frame",
    "Light",
    "LightSource",
    "OutputKind",
    "PoolPlan",
    "RenderPool",
    "SceneBody",
    "output_kinds",
    "plan_pool",
]

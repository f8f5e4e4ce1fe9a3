"""Camera rendering: worker processes (`pool.py`, `worker.py`) with their own copy of the scene
(`scene.py`), drawn by OpenGL (`gl.py`, shapes from `shapes.py`) or TinyRenderer (`tiny.py`),
finished into depth and points (`outputs.py`); what crosses the process boundary is in `specs.py`."""

from simbot.sim.render.pool import PoolPlan, RenderPool, plan_pool
from simbot.sim.render.specs import BodyState, CameraSpec, Frame, Light, SceneBody
from simbot.sim.render.worker import RENDERERS

__all__ = ["RENDERERS", "BodyState", "CameraSpec", "Frame", "Light", "PoolPlan", "RenderPool", "SceneBody", "plan_pool"]

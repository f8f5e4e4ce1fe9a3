"""Camera rendering, in worker processes that never import the simulation loop:

- the workers: the pool that runs them so that rendering never slows the physics (`pool.py`),
  how they start (`starter.py`) and are watched (`pool_workers.py`), one worker (`worker.py`) with its own copy of the scene
  (`scene.py`); what crosses the process boundary (`specs.py`) and the messages that carry it
  (`pipe.py`); the messages a worker puts on the bus itself (`publishing.py`);
- drawing: OpenGL (`gl.py`, its vertex buffers `gl_parts.py`, its shaders `gl_shaders.py`, the
  sun's shadows `gl_shadow.py`, what a view can show `culling.py`, its textures decoded once
  `textures.py`) or TinyRenderer (`tiny.py`); the bodies' visuals as the pieces a renderer shades
  (`visuals.py`, `surfaces.py`), tessellated (`shapes.py`) or read with their materials from mesh
  files (`mesh_materials.py`), skinned where an actor moves (`skinning.py`);
- finishing a camera's named outputs (their kinds: `kinds.py`): colour, mono, depth, points and
  temperature (`outputs.py`), labels packed per pixel (`label_bits.py`) into segmentation maps
  (`segmentation.py`) and bounding boxes (`boxes.py`), thermal counts (`thermal_counts.py`), lens
  distortion (`lens.py`) and wide-angle lenses (`wide_lens.py`, their outputs `wide_angle.py`).

The server side's view of a body it hands the workers: simbot.sim.kit.scene_bodies."""

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

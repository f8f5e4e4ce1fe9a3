"""The PyBullet world: its bodies added and removed, its steps, its reset, and the read-only
phase. `Physics` reads (`Queries`) and commands (`Commands`) it by name."""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from simbot.description.model import Model, World
from simbot.description.poses import Pose
from simbot.description.urdf_writer import joint_trees
from simbot.sim.bullet import pb
from simbot.sim.physics.body import Body
from simbot.sim.physics.commands import Commands
from simbot.sim.physics.guard import changes_world
from simbot.sim.physics.loading import Loader
from simbot.sim.physics.protocols import Frame
from simbot.sim.physics.rays import Rays, engine_wanted
from simbot.sim.physics.stepping import Stepper, stepper
from simbot.transform import Transform


@dataclass
class Physics(Commands):
    """A PyBullet world built from an SDF world description; stepped at the world's step size."""

    world: World
    fixed_castors: bool = True
    """Load ball castors fixed (`ball_castors`): 12 of the tug's 22 degrees of freedom gone, the same
    physics (a frictionless sphere turning about its centre moves nothing a collision sees)."""
    merge_fixed_links: bool = True
    """Load each chain of fixed joints as one link (PyBullet's URDF_MERGE_FIXED_LINKS): the tug's 21
    links become 5 (its base and four wheels), each costing the articulated-body solver and the
    broadphase as much as a moving one. A model with a contact or force/torque sensor keeps its links:
    those sensors read one link's contacts or one fixed joint's wrench."""
    ray_engine: bool = field(default_factory=engine_wanted)
    """Cast rays through the ray engine where it is installed (`rays`); False: through PyBullet."""
    client: int = field(init=False)
    bodies: dict[str, Body] = field(default_factory=dict)
    constraints: dict[int, tuple[str, str]] = field(default_factory=dict)
    _rays: Rays = field(init=False)
    _offsets: dict[tuple[str, str, Pose], Transform] = field(default_factory=dict)
    _frame_sets: list[tuple[list[Frame], tuple[list[int], npt.NDArray[np.float64]] | None]] = field(
        default_factory=list
    )
    read_only: bool = False
    """True while post-update systems run: they read the step's result and change nothing."""
    _loader: Loader = field(init=False)
    _stepper: Stepper = field(init=False)
    """Dynamic, or kinematic where the world asks (`<physics type="kinematic">`): chosen once, here."""
    _heightfields: dict[str, list[int]] = field(default_factory=dict)
    """The heightfield bodies of each model's heightmaps (PyBullet bodies apart from the model's)."""
    _saved_state: int | None = None
    _saved_bodies: tuple[str, ...] = ()
    _tmp: tempfile.TemporaryDirectory[str] = field(default_factory=tempfile.TemporaryDirectory)

    def __post_init__(self) -> None:
        self.client = pb.connect(pb.DIRECT)
        pb.setGravity(*self.world.gravity, physicsClientId=self.client)
        pb.setTimeStep(self.world.physics.max_step_size, physicsClientId=self.client)
        pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=self.client)
        self._stepper = stepper(self.world, self.client)
        self._loader = Loader(self.client, Path(self._tmp.name), self.fixed_castors, self.merge_fixed_links)
        self._rays = Rays(self.client, Path(self._tmp.name), self.ray_engine)

    def close(self) -> None:
        """Disconnects PyBullet and removes the generated URDF files."""
        if pb.isConnected(self.client):
            pb.disconnect(self.client)
        self._tmp.cleanup()

    # building

    @changes_world
    def add_model(self, model: Model, name: str | None = None, pose: Pose | None = None) -> Body:
        """Loads `model` (through its URDF) as `name` at `pose` (default: the model's own pose).

        A model whose links form several joint trees is loaded as one body per tree (see
        `joint_trees`): the main one is `name` and is returned; each other is `name::<its root>`."""
        name = name or model.name
        main, *others = joint_trees(model)
        body = self._add_tree(main, name, pose)
        for part in others:
            self._add_tree(part, name + part.name.removeprefix(model.name), pose)
        return body

    def _add_tree(self, model: Model, name: str, pose: Pose | None) -> Body:
        """One tree of joints as one PyBullet body."""
        if name in self.bodies:
            raise ValueError(f"a model named {name!r} is already in the world")
        loaded = self._loader.load(model, name, pose)
        self.bodies[name] = loaded.body
        self._frame_sets.clear()
        self._stepper.add(loaded.body, loaded.wheels)
        self._heightfields[name] = loaded.heightfields
        self._rays.add(loaded.body)
        return loaded.body

    def restyle(self, name: str, model: Model) -> None:
        """`model` described anew where the physics simulates nothing of what changed (its looks, an
        actor's script, its sensors' parameters): its bodies stay as loaded, with the URDF they were
        loaded from; `model_of` gives the new description (a seeded reset edits the world in place)."""
        for tree in joint_trees(model):
            self.body(name + tree.name.removeprefix(model.name)).model = tree

    @changes_world
    def remove_model(self, name: str) -> list[str]:
        """Takes `name` out of the world with its further joint trees (`name::<root>`), its wheels'
        friction, its cached frames and its ray group (free for the next robot); returns the bodies'
        names. Joints made by `attach` are their system's to undo first."""
        self.body(name)
        names = [n for n in self.bodies if n == name or n.startswith(name + "::")]
        for part in names:
            body = self.bodies.pop(part)
            self._stepper.forget(body.id)
            self._offsets = {k: v for k, v in self._offsets.items() if k[0] != part}
            self._frame_sets.clear()
            self._rays.remove(part)
            for heightfield in self._heightfields.pop(part, []):
                pb.removeBody(heightfield, physicsClientId=self.client)
            pb.removeBody(body.id, physicsClientId=self.client)
        return names

    @contextmanager
    def reading(self) -> Iterator[None]:
        """The world read-only for the duration (the post-update phase)."""
        self.read_only = True
        try:
            yield
        finally:
            self.read_only = False

    def save_initial_state(self) -> None:
        """Remembers the world as built, for `reset`, in place of what it remembered (a seeded reset
        saves each variant it applies)."""
        if self._saved_state is not None:
            pb.removeState(self._saved_state, physicsClientId=self.client)
        self._stepper.sync()
        self._saved_state = pb.saveState(physicsClientId=self.client)
        self._saved_bodies = tuple(self.bodies)

    # stepping

    @changes_world
    def step(self) -> None:
        """One physics step: wheel friction from the last contacts, then PyBullet; in kinematic mode
        the drives' motions and a collision check (`stepping`)."""
        self._stepper.step(self.bodies)

    @changes_world
    def reset(self) -> None:
        """Every body back to where it was built, at rest; detachable joints are the systems' to undo.
        PyBullet restores bodies by their order: the world must hold the bodies it was saved with."""
        if tuple(self.bodies) != self._saved_bodies:
            gone = sorted(set(self._saved_bodies) - set(self.bodies))
            raise ValueError(f"reset: the world as started held {', '.join(gone)}, removed since; restart the server")
        if self._saved_state is not None:
            pb.restoreState(self._saved_state, physicsClientId=self.client)
            self._stepper.restored()
            self._rays.moved(list(self.bodies.values()))

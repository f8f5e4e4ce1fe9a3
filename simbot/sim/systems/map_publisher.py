"""`map`: the running world's ground-truth map, latched, as nav_msgs/OccupancyGrid (docs/map.md).

A world system (built in, no `<plugin>`). The map is every static model's collision geometry
cut at the tug's lidar height (simbot.mapping: the same rasterising as `simbot map`), in frame
`map`, which is the world's (REP-105: the map of a simulator is exact, so `map` → `world` is the
identity), stamped with the sim time it was made at (its `map_load_time` too). Data as ROS has it:
row-major from the origin cell (lowest x and y), 0 free, 100 occupied; RViz and Foxglove draw it
under the scans.

| parameter | value | what |
| --- | --- | --- |
| height | 0.355 m above the floor (`LIDAR_HEIGHT`) | where the lidars' beams sweep: 0.26 m above base_footprint, which rests 0.0955 m up |
| resolution | 0.05 m (`RESOLUTION`) | Nav2's usual |
| extent | the static models' (`simbot.mapping.occupancy`) | the warehouse: ±10 m |
| people | no | they move; `simbot map --people` draws them at time 0 |

It follows the model events: a static model created through world control (a randomised world's
clutter) joins the map, a removed one (a reset takes created models out) leaves it. Each model is
cut once, when it enters (the models there at start at their description's poses, so the map is
`simbot map`'s, cell for cell; a created one where the physics put it); a step in which static
models came or went re-fills the grid once, from the cut pieces (the warehouse: about 5 ms of CPU),
and never in another step; the message is encoded and put on the scene's sender thread, at once
in lockstep (simbot.sim.kit.latest_sender.LatestSender).
"""

from __future__ import annotations

import numpy as np

from simbot.bus import messages
from simbot.description.actor_scripts import is_actor
from simbot.description.model import World
from simbot.description.poses import Pose
from simbot.mapping.occupancy import LIDAR_HEIGHT, RESOLUTION, OccupancyGrid, model_pieces, rasterise
from simbot.mapping.shapes import Band, Pieces
from simbot.sim.kit.latest_sender import LatestSender
from simbot.sim.loop.system import ModelEvent, SystemContext, UpdateInfo
from simbot.sim.physics import WorldReader

MAP_TOPIC = "map"
MAP_FRAME = "map"
OCCUPIED, FREE = 100, 0


def grid_message(grid: OccupancyGrid, now_ns: int) -> object:
    """nav_msgs/OccupancyGrid of `grid` in `map`, stamped `now_ns`."""
    cells = np.where(grid.occupied, OCCUPIED, FREE).astype(np.int8)
    return messages.occupancy_grid(now_ns, MAP_FRAME, grid.resolution, (*grid.origin, 0.0), cells)


class MapPublisher:
    """A world system (built in, no `<plugin>`): see the module docstring."""

    name = "MapPublisher"

    def __init__(self, ctx: SystemContext) -> None:
        self._physics: WorldReader = ctx.physics
        self._world: World = ctx.world
        self._band = Band.at(LIDAR_HEIGHT)
        publisher = ctx.bus.publisher(MAP_TOPIC, messages.OccupancyGrid, latched=True)
        self._sender = LatestSender(publisher, at_once=ctx.options.lockstep)
        self._pieces: dict[str, Pieces] = {}
        self._changed = False

    def model_added(self, event: ModelEvent) -> None:
        for body in event.bodies:
            model = self._physics.model_of(body)
            if model.static and not is_actor(model):
                self._pieces[body] = model_pieces(model, self._pose(event, body), self._band)
                self._changed = True

    def _pose(self, event: ModelEvent, body: str) -> Pose:
        """Where a model there from the start stands by its description (exact, as `simbot map` has
        it); a created one where the physics holds it."""
        if not event.created:
            described = next((m for m in self._world.models if m.name == event.name), None)
            if described is not None:
                return described.pose
        return Pose.from_transform(self._physics.model_pose(body))

    def world_changed(self, world: World) -> None:
        """A seeded reset edited the world in place: the models' described poses are the variant's."""
        self._world = world

    def model_removed(self, event: ModelEvent) -> None:
        for body in event.bodies:
            if self._pieces.pop(body, None) is not None:
                self._changed = True

    def post_update(self, info: UpdateInfo) -> None:
        if self._changed:
            self._changed = False
            grid = rasterise(list(self._pieces.values()), RESOLUTION)
            self._sender.send(grid_message(grid, info.sim_time_ns))

    def close(self) -> None:
        self._sender.close()

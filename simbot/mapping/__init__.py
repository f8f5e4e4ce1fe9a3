"""Ground-truth maps: a world's collision geometry rasterised into an occupancy grid
(`occupancy`, cut per shape by `shapes`, filled by `raster`), written for Nav2's map_server
(`nav2_map`), from the command line as `simbot map` (`command`). The description layer and numpy
only: the running world's map on the bus is simbot.sim.systems.map_publisher's."""

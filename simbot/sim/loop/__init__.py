"""The simulation loop's core: the contract every system implements (`system.py`), the loop that
steps them (`simulation.py`), the running world that loads models and creates, removes and resets
them (`world.py`), world control on the bus (`world_control.py`), which systems an SDF asks for and
which were left out (`sdf_systems.py`, `registry.py`), and what a system may do on the bus and the
names it derives from its SDF (`bus_view.py`, `naming.py`)."""

"""What the systems share, none of it the loop: the drives' cmd_vel → wheel speeds and odometry
(`drive.py`), the joint controllers' PID (`pid.py`), reading a `<plugin>`'s and a `<sensor>`'s
parameters (`plugin_params.py`, `sensor_params.py`), rates in sim time (`rates.py`), where an actor
is at a sim time (`actor_paths.py`), a camera's `<save>` (`camera_save.py`), and what camera
sensors and the rendering system agree on (`rendered_sensor.py`)."""

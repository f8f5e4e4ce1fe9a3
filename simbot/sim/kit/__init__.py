"""What the systems share, none of it the loop (a system imports the kit and the layers below it,
never another system but the camera a camera of another kind specialises):

- drives and joints: a drive's command from its key to what it applies, ramped and clamped
  (`command_pipeline.py`), cmd_vel → wheel speeds and odometry (`drive.py`), the joint controllers'
  commanded joints and the joint-state rate (`joints.py`), their PID (`pid.py`);
- sensors: channel noise and the sensor that reads its own frame (`sensors.py`), rates in sim time
  (`rates.py`);
- cameras: what camera sensors and the rendering system agree on, and what an annotating system
  covers (`rendered_sensor.py`), a body as the render workers get it (`scene_bodies.py`), a
  camera's `<save>` (`camera_save.py`);
- actors: the system that moves an actor in place of its script (`actor_driver.py`), the social
  force by which people walk, every person of a world in one pass (`social_force.py`), what they
  see of the world (`crowd_view.py`), the waypoints a plugin states (`waypoints.py`);
- a latched message put on the bus from a thread of its own (`latest_sender.py`).

The parameters of a `<plugin>` or a `<sensor>`, and the typed parameters other layers read too
(DiffDrive, lidar, SocialForce), are the description layer's (simbot.description: `plugin_params`,
`sensor_params`, `drive_params`, `lidar_params`, `crowd_params`), as are the names a system derives
from its SDF (`naming`) and where an actor's script has it (`actor_paths`)."""

"""simbot's client programs: each is a small process that talks to the server only over the bus.

teleop, merger, stitcher and dock have console scripts of their own (`simbot-teleop`, ...); all of
them, with topics, echo, monitor, snapshot and launch, are also `simbot <command>`.
"""

"""The contract of an actor's own system that moves it in place of its script (FollowActor,
SocialForce): where an actor is at a sim time by its script is simbot.description.actor_paths."""

from __future__ import annotations

from typing import Protocol, runtime_checkable


@runtime_checkable
class ActorDriver(Protocol):
    """An actor's own system that moves it in place of its script (FollowActor), as a TrajectoryPose
    component overrides the script in gz-sim: the actors system leaves such an actor to it."""

    drives_actor: bool

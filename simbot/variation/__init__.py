"""Randomised worlds: a world's variation profile and the variant a seed draws from it.

`simbot-server --randomise SEED[:PROFILE]`, world control's `reset` with a seed, the Gymnasium
environments' `reset(seed=...)` and `simbot dataset --randomise` all load `vary(...)`'s world.
docs/variation.md describes the profile."""

from simbot.variation.profile import Profile, ProfileError, profile_beside, read_profile, seed_option
from simbot.variation.vary import Variant, Variations, vary

__all__ = ["Profile", "ProfileError", "Variant", "Variations", "profile_beside", "read_profile", "seed_option", "vary"]

"""agrisim's Gymnasium environments, registered when this package is imported (Gymnasium 1.0
dropped the plugin entry point; Gymnasium-Robotics registers the same way)::

    import gymnasium as gym
    import agrisim.envs  # noqa: F401

    env = gym.make("agrisim/PlantView-v0", plant="coltsfoot")
    # or, without the import: gym.make("agrisim.envs:agrisim/PlantView-v0")

``agrisim/PlantView-v0``: :class:`agrisim.plugins.apps.nextview.env.PlantViewEnv`.
"""

from __future__ import annotations

import gymnasium as gym

# max_episode_steps is left to the environment's own max_views (its truncation), so that a
# TimeLimit wrapper does not cut an episode before its run is finished and written
if "agrisim/PlantView-v0" not in gym.registry:
    gym.register(id="agrisim/PlantView-v0", entry_point="agrisim.plugins.apps.nextview.env:PlantViewEnv")

"""The exact mixed-integer footstep search that the footstep planners share: a planner poses
its solve as a ``CondensedQp`` over foothold assignments; ``ExactSearch`` finds the global
optimum over them with piqp QPs (``QpEngine``); ``WorldFootholds`` turns the world's
footholds into the stance frame's (``LocalFootholds``)."""

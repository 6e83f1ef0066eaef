"""The MuJoCo process standing in for Cassie's real-time target PC.

``sim.model`` loads Cassie from MuJoCo Menagerie and adds terrain; ``sim.terrain`` makes
terrains and their ground-truth footholds; ``sim.camera`` is the ray-cast D455;
``sim.target_pc`` is the transport-free core (physics, watchdog, holder, packets, modes);
``sim.process`` wraps it as a ``runtime.node.Node`` (``make_node``).
"""

"""The Cassie runtime library: LCM bus, loops, timing, harness, config and supervisor."""

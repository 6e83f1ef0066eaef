"""Benchmarks run by `cassie bench NAME`; each module exposes `main(argv) -> int`."""

"""User-facing programs: the `cassie` CLI, launcher, dashboard, reports and benchmarks."""

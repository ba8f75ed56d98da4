"""Command modules of the `deploy` CLI, one per area; each has `register(app, bench_app)`."""

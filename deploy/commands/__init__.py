"""The `deploy` command groups, one module each (deploy/cli.py assembles them); output.py and options.py are
what they share."""

"""What an episode or a recording leaves for people to look at: the run folder (run_folder.py: frames, config.json,
steps.json), its plots (episode_plot.py: report.png) and the rerun viewer (viewer.py: `--view`, `export --format
rrd`). Files and plots only: nothing here decides anything."""

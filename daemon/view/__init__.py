"""The live view: `--foxglove [HOST:PORT]` and `--mcap FILE` on run, replay and demo.

frames.py converts and packs (numpy only), publisher.py speaks Foxglove (the optional foxglove-sdk), options.py is
the command line's side. Nothing here imports foxglove until a view is asked for: a daemon without the options
never loads it.
"""

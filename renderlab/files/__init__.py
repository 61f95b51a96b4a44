"""Files the lab writes and reads: :mod:`.truthset` (truth-set folders), :mod:`.imageio` (EXR and DN PNG images)
and :mod:`.signals` (SIGTERM/SIGHUP end a command like Ctrl-C; staging folders of crashed runs are removed)."""

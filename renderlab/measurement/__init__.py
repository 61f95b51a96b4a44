"""Landmark measurement: the runner (truth set or plain images → the measurement table) and the built-in
method adapters (Retina, SPC-style) registered in :data:`renderlab.plugins.landmark_methods`."""

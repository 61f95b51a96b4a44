"""Truth worlds: analytic scenes, EV5, Earth, microsatellite."""

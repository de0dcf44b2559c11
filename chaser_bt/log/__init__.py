"""Flight logs: the per-tick trace of a flight, the MCAP recorder, replay and the paper's figures."""

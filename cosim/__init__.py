"""Co-simulation: SUMO traffic, the frame loop, the command line, sweeps."""

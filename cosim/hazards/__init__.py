"""Hazard events without SUMO: when they are due and what the rig sees
(:mod:`cosim.hazards.plan`), and the decisions the events take from what SUMO reports
(:mod:`cosim.hazards.decisions`: where vehicles are relative to the ego, pacing, who runs a red
light, when the ego stops for a jaywalker).

The events themselves are made with SUMO's commands in :mod:`cosim.sumo.hazards`.
"""

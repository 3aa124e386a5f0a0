"""Hazard events without SUMO: when they are due and what the rig sees (:mod:`cosim.hazards.plan`).

The events themselves are made with SUMO's commands in :mod:`cosim.sumo.hazards`.
"""

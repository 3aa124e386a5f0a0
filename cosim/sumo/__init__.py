"""The SUMO boundary: the only code that imports libsumo.

:mod:`cosim.sumo.traffic` starts the simulation, feeds it demand, picks the ego and reads
world states (SUMO's angles, front bumpers and vehicle types decoded into the map frame and
the project's classes); :mod:`cosim.sumo.people` keeps people along the ego's way;
:mod:`cosim.sumo.hazards` makes hazard events with SUMO's commands. What needs no simulation
(when events are due, what the rig sees, the hazards' decisions) is in :mod:`cosim.hazards`.
"""

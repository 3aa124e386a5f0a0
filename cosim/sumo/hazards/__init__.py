"""Hazard events made on purpose near the ego, with SUMO's own commands (:mod:`cosim.sumo.hazards.roads`
reads the roads around the ego; the decisions that need no SUMO are in :mod:`cosim.hazards`).

Each hazard kind of the scenario is due ``per_minute`` times a simulated minute: one event in
each period of 60 / per_minute seconds, at a time drawn in its middle half (from the scenario's
seed; :mod:`cosim.hazards.plan`). Before an event is due, its actor is prepared: found in the
traffic around the ego and brought into place, or, where the traffic has none, made where no
sensor of the rig sees it and no label reaches (:class:`~cosim.hazards.plan.Sight`: a car on
the road the ego came along, far enough behind, or on its way far enough ahead, or on a
crossing approach; a pedestrian at a kerb far enough ahead), so that it drives or walks into
view as any other road user. The event starts when it is due and its actor is in place (an
event that had to wait does not push the next ones back: up to two a kind are owed). The
first events are prepared during the last part of the warm-up (``HazardController.lead_s``).

Cut-ins and hard braking start only where the ego's way (its lane and the lanes its route goes
on) runs straight ahead (a time to collision under constant velocity means little in a bend),
a hard brake also on a gentle bend when its leader is in line with the ego; jaywalkers cross
straight roads (their direction is fixed when they step out).

- ``cut_in``: a vehicle in a lane beside the ego going its way (the first in that lane on
  either side of the place wanted, from as far behind as a car is made to 40 m ahead; where a
  lane beside the ego is empty, a car made out of sight behind the ego) is paced so that it
  is a gap within ``distance_m`` and ``time_gap_s`` ahead, at the ego's pace, when the event
  is due; then it changes into the ego's lane at once (lane-change mode 0: SUMO's safety
  checks off for this change) and slows to half the ego's speed within 2 s (braking at most
  at 4 m/s^2), holding it 4 s. The ego keeps its lane meanwhile and its driver reacts 0.6 s
  late (SUMO's action step length), then brakes with SUMO's car-following.
- ``hard_brake``: the ego's leader (within what the rig sees ahead, routed along the ego's
  way; where the ego has none, a car made on its way ahead beyond the rig's sight) is paced
  from the ego's free speed to a gap within ``distance_m`` and brakes at ``decel_mps2`` to
  ``to_speed_mps`` once it has led for 3 s, holds it 2 s, then drives on; the ego keeps its
  lane and follows with SUMO's car-following.
- ``jaywalker``: a pedestrian (by default a child of Euro NCAP's child target size) steps off
  the kerb on the ego's side and walks across at ``walk_mps`` outside any crossing, where it
  reaches the ego's path when the ego is its braking distance (at 7.5 m/s^2) plus 5 m away
  (within ``distance_m``): with ``behind_parked``, from just before the front bumper of the
  parked car on the ego's way that the ego comes to nearest the time it is due, in line behind
  it as the ego sees it (placed there as it steps out, hidden by the car); elsewhere from where
  it stood waiting at the kerb, placed before the rig could see it. The ego brakes (up to
  7.5 m/s^2) for a pedestrian within 40 m ahead that is in its path or will be before it
  could stop.
- ``red_light``: while the ego approaches a green light ``distance_m`` away, a vehicle on a
  crossing approach with red (moving, or the first in its queue) drives through (speed mode 7:
  red lights and right of way ignored), timed to clear the junction at least 1.5 s before the
  ego can reach it at its speed, or, when it cannot, slowed to enter 1.5 s after the ego has
  crossed. A light the ego would stop at turns green for it as it comes (the crossing green
  ends through its yellow, as at an actuated light); where no crossing vehicle could run the
  red, a car is made on a crossing approach out of the rig's sight.

An event ends after a fixed time (cut_in 6 s, hard_brake when its hold ends, jaywalker when
the pedestrian has crossed, red_light 10 s) or when an actor leaves the simulation; the
actors (and the ego) get their SUMO settings back. A pedestrian who crossed (or waited in
vain) is taken out of the simulation once no sensor sees it. :meth:`HazardController.active`
lists the events under way, which the world state carries to the labels.
"""

from cosim.sumo.hazards.controller import HazardController
from gtgen.frame import ActiveHazard

__all__ = ["ActiveHazard", "HazardController"]

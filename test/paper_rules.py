"""Paper planner switches for causal tests that isolate one rule.

Several rules can each lead the robot into the same region: a door beside a corner is found by
a dead end's gap, a cusp read as a meet point, or a meet point taken in a half-plane or just
beyond delta. A causal test shows that its own rule decides, by patching that rule out and
seeing the region stay unentered; so it runs with the rules that also lead there switched
off, lest another rule enter the region instead.
"""

#: meet points only where their three closest obstacles surround them and within delta, a
#: boundary circuit back at its start going either way and on either side, and past a meet
#: point the GVD law of the two closest with every peak near the way behind the way come, and a
#: meet point sensed near a known one that one (each switch's other setting)
LATER_RULES_OFF = {'meet_surround': True, 'meet_margin': 0.0, 'circuit_same_way': False,
                   'circuit_same_side': False, 'meet_side_pair': False, 'way_come_held': False,
                   'meet_own_obstacles': False}

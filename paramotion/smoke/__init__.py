"""The smoke graph: the smallest complete paramotion graph, and the template for robots.

A PyBullet cart on a rail (``smoke_sim``, owns ``/clock``), a range sensor looking at a wall
(``smoke_range_sensor``) and a controller that stops the cart at a set distance from the wall
using only the sensor (``smoke_controller``). The pure math is in :mod:`.control`.
"""

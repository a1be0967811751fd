"""The coverage sonar's ray caster (coverage_pkg.sonar.RingCaster) finds the ranges the world's
ray cast (coverage_pkg.world.raycast_segments) gives, bit for bit: the sonar node casts with
segments and cone offsets computed once, and bag replays depend on its readings."""
import math

import numpy as np

from coverage_pkg.sonar import RingCaster, SonarRing
from coverage_pkg.world import load_world, random_world


def test_ring_caster_finds_the_world_ray_cast_ranges_bit_for_bit():
    worlds = [load_world('coverage_pkg/worlds/two_rooms.json', radius=0.25),
              random_world(3), random_world(11)]
    rings = [SonarRing(), SonarRing(count=5, beam_width=0.6, rays_per_beam=4, max_range=2.5,
                                    min_range=0.3)]
    rng = np.random.default_rng(2)
    kinds = set()
    for world in worlds:
        xmin, ymin, xmax, ymax = world.bounds
        for ring in rings:
            caster = RingCaster(world, ring)
            offsets = np.linspace(-0.5, 0.5, ring.rays_per_beam) * ring.beam_width
            for _ in range(150):
                x, y, yaw = (rng.uniform(xmin, xmax), rng.uniform(ymin, ymax),
                             rng.uniform(-math.pi, math.pi))
                angles = yaw + ring.mount_angles()[:, None] + offsets[None, :]
                want = world.raycast((x, y), angles, 2.0 * ring.max_range).min(axis=1)
                got = caster.true_ranges((x, y, yaw))
                assert np.array_equal(got, want), (world.name, (x, y, yaw), got, want)
                readings = caster((x, y, yaw))
                kinds |= {'inf' if v == math.inf else '-inf' if v == -math.inf else 'echo'
                          for v in readings}
    assert kinds == {'inf', '-inf', 'echo'}     # ranges of every REP 117 kind were compared

"""KNTU workspace figure for ``paramotion bench``."""


def bench_kntu(quick: bool, options: dict) -> dict:
    """Constant-orientation workspace poses/s at step 0.05 m (the ``workspace cow`` path)."""
    from cable_robot_pkg.cdrpm.workspace import benchmark_cow
    res = benchmark_cow(step=0.05, repeats=1 if quick else 7)
    return {'kntu_poses_per_s': float(res['kntu_poses_per_s']),
            'kntu_backend': res.get('kntu_backend')}


# name -> (function(quick, options) -> figures, {key: table label})
BENCHES = {'kntu': (bench_kntu, {'kntu_poses_per_s': 'KNTU cow poses/s (step 0.05)'})}

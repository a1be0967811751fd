"""``paramotion workspace``: geometric workspace of the KNTU CDRPM (Aref & Taghirad).

This module only parses arguments; each analysis is a module of its own beside it
(``cow``, ``table2``, ``orientation``, ``tow``, ``workpiece``, ``wrench``, ``arrangements``,
``bench``) that calls the computation in :mod:`cable_robot_pkg.cdrpm` and writes
``DIR/result.json`` and a PNG (``table2`` and ``bench`` print a table and may write JSON).

``--robot`` defaults to the shipped Neuron description
(cable_robot_pkg/cdrpm/config/kntu_neuron.yaml), an arrangement fitted to Table II and the TOW
box (the paper does not publish its anchors).
"""
from cable_robot_pkg.cdrpm.cli import (
    arrangements,
    bench,
    cow,
    heldout,
    orientation,
    table2,
    tow,
    workpiece,
    wrench,
)


def register(subparsers):
    """Add ``paramotion workspace {cow,table2,orientation,tow,workpiece,wrench,arrangements,
    heldout,bench}``."""
    from paramotion.sweep import add_dask_args

    parser = subparsers.add_parser(
        'workspace', help='KNTU CDRPM collision-free workspace (Aref & Taghirad)',
        description='Geometric workspace analysis of a cable-driven redundant parallel '
                    'manipulator: constant-orientation, orientation and total orientation '
                    'workspaces, workpiece study, wrench closure and a speed benchmark.')
    sub = parser.add_subparsers(dest='workspace_command', metavar='ACTION')
    sub.required = True

    def robot_arg(p):
        p.add_argument('--robot', help='robot description YAML (default: the Neuron '
                       'arrangement fitted to Table II and the TOW box)')

    def without_arg(p):
        p.add_argument('--without', action='append', default=[], metavar='NAME',
                       help='switch a construct off (repeatable): cable_cable, cable_body, '
                            "cable_workpiece, workpiece_sides (the paper's top-plane test "
                            'instead of the full box)')

    p = sub.add_parser('cow', help='constant-orientation workspace (IV-A, Fig. 6)',
                       description='Accessible centroid positions at one orientation; writes '
                                   'DIR/result.json and DIR/cow.png.')
    robot_arg(p)
    p.add_argument('--rot', nargs=3, type=float, required=True, metavar=('RX', 'RY', 'RZ'),
                   help='orientation in degrees (R = Rx Ry Rz)')
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--out', required=True, help='output directory')
    without_arg(p)
    p.set_defaults(func=cow.run)

    p = sub.add_parser('table2', help="the paper's Table II beside ours",
                       description="Accessible percentage (eq. (10)) for the rows of the "
                                   "paper's Table II.")
    robot_arg(p)
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--out', help='optional directory for result.json')
    without_arg(p)
    p.set_defaults(func=table2.run)

    p = sub.add_parser('orientation', help='orientation workspace at a position (IV-B, Fig. 7)',
                       description='Accessible (r_x, r_y) for several r_z at one position; '
                                   'writes DIR/result.json and DIR/orientation.png.')
    robot_arg(p)
    p.add_argument('--position', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                   metavar=('X', 'Y', 'Z'), help='platform centroid in m (default origin)')
    p.add_argument('--rz', nargs='+', type=float, default=[0.0, 10.0, 20.0, 30.0],
                   help='r_z values in degrees (default 0 10 20 30)')
    p.add_argument('--max-angle', type=float, default=90.0,
                   help='scan r_x, r_y over +-this many degrees (default 90)')
    p.add_argument('--angle-step', type=float, default=1.0, help='degrees (default 1)')
    p.add_argument('--out', required=True, help='output directory')
    without_arg(p)
    p.set_defaults(func=orientation.run)

    p = sub.add_parser('tow', help='total orientation workspace and largest box (IV-C)',
                       description='Intersection of the COWs over a +-theta box of '
                                   'orientations and the largest axis-aligned box inside it; '
                                   'writes DIR/result.json and DIR/tow.png.')
    robot_arg(p)
    p.add_argument('--theta', nargs=3, type=float, default=[30.0, 30.0, 10.0],
                   metavar=('TX', 'TY', 'TZ'), help='half ranges in degrees (default 30 30 10)')
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--angle-step', type=float, default=10.0,
                   help='orientation sampling step in degrees (default 10)')
    p.add_argument('--out', required=True, help='output directory')
    without_arg(p)
    p.set_defaults(func=tow.run)

    p = sub.add_parser('workpiece', help='workpiece study on the plane y = 0 (IV-D)',
                       description='COW on the vertical plane y = 0 with and without a box '
                                   'workpiece on the floor centre; writes DIR/result.json and '
                                   'DIR/workpiece.png.')
    robot_arg(p)
    p.add_argument('--size', nargs=3, type=float, default=None, metavar=('WX', 'WY', 'WZ'),
                   help="workpiece size in m (default: the description's, else 1 1 0.5)")
    p.add_argument('--rot', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                   metavar=('RX', 'RY', 'RZ'), help='platform orientation in degrees')
    p.add_argument('--step', type=float, default=0.02, help='grid step in m (default 0.02)')
    p.add_argument('--out', required=True, help='output directory')
    without_arg(p)
    p.set_defaults(func=workpiece.run)

    p = sub.add_parser('wrench', help='wrench-closure workspace (beyond the paper)',
                       description='Where positive cable tensions can balance any wrench, '
                                   'compared with the collision-free workspace; writes '
                                   'DIR/result.json and DIR/wrench.png.')
    robot_arg(p)
    p.add_argument('--rot', nargs=3, type=float, default=[0.0, 0.0, 0.0],
                   metavar=('RX', 'RY', 'RZ'), help='orientation in degrees')
    p.add_argument('--step', type=float, default=0.05, help='grid step in m (default 0.05)')
    p.add_argument('--out', required=True, help='output directory')
    p.set_defaults(func=wrench.run)

    p = sub.add_parser('arrangements', help='search cable arrangements (the fitted Neuron)',
                       description='Search the cable arrangements behind the shipped Neuron for '
                                   'the dimensions of --robot: frame anchors on the frame edges '
                                   '(--pitch), symmetric under the half turns about x, y and z, '
                                   'wrench-closed and collision-free at the home pose, ranked by '
                                   'the collision-free and wrench-closed share of the grid x '
                                   '(+-30, +-30, +-10 deg) box. With --corners: the older search '
                                   'of corner-to-corner pairings at zero rotation. Writes '
                                   'DIR/result.json with --out.')
    robot_arg(p)
    p.add_argument('--corners', action='store_true',
                   help='search corner-to-corner pairings instead (zero rotation only)')
    p.add_argument('--table2', action='store_true',
                   help="fit the Neuron to the paper's results instead: Table II "
                        'within 5 points on the in-frame grid and the TOW box 1.2 x 1.2 x 1.4 '
                        'm (the search behind the shipped default; about 5-10 minutes)')
    p.add_argument('--pitch', type=float, default=0.1,
                   help='anchor spacing along the frame edges in m (default 0.1)')
    p.add_argument('--min-gap', type=float, default=0.02,
                   help='smallest cable surface gap at the home pose in m (default 0.02)')
    p.add_argument('--step', type=float, default=0.2, help='grid step in m (default 0.2)')
    p.add_argument('--top', type=int, default=12, help='rows to print (default 12)')
    p.add_argument('--out', help='optional directory for result.json')
    add_dask_args(p)  # candidates evaluated as Dask tasks (docs/sweeps.md)
    p.set_defaults(func=arrangements.run)

    p = sub.add_parser('heldout', help="which arrangements reproduce the paper's held-out "
                       'figures with the fitted ones',
                       description='For every edge-anchored candidate of the fit: Fig. 7 trend '
                                   '(r_y limit against r_x at the centre, and the type that sets '
                                   'it) and the workpiece share; for those near Table II also '
                                   'Table II on the 0.05 m grid, the TOW box and a scan of '
                                   'workpiece sizes. Writes DIR/result.json (about 10 minutes '
                                   'on one core).')
    robot_arg(p)
    p.add_argument('--pitch', type=float, default=0.1,
                   help='anchor spacing along the frame edges in m (default 0.1)')
    p.add_argument('--sample', type=int, default=1000,
                   help='candidates far from Table II evaluated, at random (default 1000; '
                        '-1: all, several times longer)')
    p.add_argument('--out', required=True, help='output directory')
    add_dask_args(p)
    p.set_defaults(func=heldout.run)

    p = sub.add_parser('bench', help='COW poses per second with all checks',
                       description="Median wall time of the COW at 30/30/10 deg on a grid of "
                                   "about 148,000 points (the paper's 373 s), all checks on.")
    robot_arg(p)
    p.add_argument('--points', type=int, default=148000,
                   help='approximate grid size (default 148000, as in the paper)')
    p.add_argument('--runs', type=int, default=7, help='timed runs (default 7)')
    p.add_argument('--rot', nargs=3, type=float, default=[30.0, 30.0, 10.0],
                   metavar=('RX', 'RY', 'RZ'), help='orientation in degrees (default 30 30 10)')
    p.add_argument('--out', help='optional directory for result.json')
    p.set_defaults(func=bench.run)

"""Choice between the compiled (numba) kernels and their numpy fallbacks.

numba is an optional speed-up: every kernel has a numpy implementation that computes the same
thing and is tested against it. ``backend='auto'`` uses numba when it is importable, unless the
environment variable ``PARAMOTION_BACKEND`` says ``numpy`` (or ``numba``, to insist).
"""
from __future__ import annotations

import os

#: Accepted backends; ``PARAMOTION_BACKEND`` (``numba`` or
#: ``numpy``) overrides ``'auto'``, which means numba when it is installed.
BACKENDS = ('auto', 'numba', 'numpy')


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity mask, not the machine's count), >= 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def resolve_backend(backend: str = 'auto') -> str:
    """``'numba'`` or ``'numpy'``: the compiled kernels when asked for and importable."""
    if backend not in BACKENDS:
        raise ValueError(f'backend must be one of {BACKENDS}, got {backend!r}')
    if backend == 'auto':
        backend = os.environ.get('PARAMOTION_BACKEND', 'auto').strip().lower() or 'auto'
        if backend not in BACKENDS:
            raise ValueError(f'PARAMOTION_BACKEND must be numba or numpy, got {backend!r}')
    if backend == 'numpy':
        return 'numpy'
    try:
        import numba  # noqa: F401
    except ImportError:
        if backend == 'numba':
            raise
        return 'numpy'
    return 'numba'

"""
Compiled time loops of the stateful damper models (numba), cached on disk.

The stateful models integrate an internal state sample by sample. numpy can vectorise that only
over the particles of a swarm, paying a Python-level loop iteration and a dozen small array
operations per time step and sub-step. The loops are therefore written once, as plain Python over
scalars, in the model modules themselves (``bouc_wen._z_loop``, ``spencer._force_loop``, with
the helpers they call, such as ``spencer.z_step_rooted``), and compiled here with numba on first
use. The compiled loop keeps the order of the numpy code: time outer, the whole swarm inner.

Cache. Kernels are compiled with ``cache=True``: numba stores the machine code in the
``__pycache__`` folder beside the model module (for the editable install of this repository,
``src/mr_damper_model/mr_damper_model/__pycache__/<module>._<loop>-<line>.py311.*.nbc`` and its
``.nbi`` index), keyed by the source file's content hash, the argument types and the CPU. A later
process loads it instead of compiling. Because the helpers are compiled from the same source
file, editing any of them changes the hash and the next call recompiles. numba picks the folder
in this order: ``NUMBA_CACHE_DIR`` if set; the module's ``__pycache__`` if writable; the user-wide
cache ``$XDG_CACHE_HOME/numba`` (``~/.cache/numba``); otherwise no cache folder is available and
the kernel is compiled in memory in every process (:func:`cache_status` says which).

Helpers from other modules. A kernel of another package (the car step of ``mr_damper_gym``)
reuses the models' own helpers (``spencer.heun_substeps``, ``kwok_current_force_scalar``) by
passing the functions themselves: each is compiled in its own module's namespace and inlined
like a local helper. numba's cache only watches the kernel's own source file, so the kernel's
cache name then carries a digest of the helpers' source files: editing one of them gives a new
name, and the next call compiles afresh instead of loading stale machine code.
"""
import hashlib
import inspect
import threading
import types

__all__ = ['kernel', 'cache_status']

_LOCK = threading.Lock()
_KERNELS = {}
_CACHE_ERRORS = {}


def _rebind(func, namespace):
    """Copy of ``func`` that resolves its global names in ``namespace``."""
    new = types.FunctionType(func.__code__, namespace, func.__name__, func.__defaults__,
                             func.__closure__)
    new.__qualname__ = func.__qualname__
    new.__module__ = func.__module__
    new.__doc__ = func.__doc__
    return new


def _helper_namespaces(func, helpers, namespace):
    """Return ``{name: (function, namespace it is compiled in)}`` and the foreign source files."""
    found = {}
    foreign = set()
    for helper in helpers:
        if isinstance(helper, str):
            py, ns = func.__globals__[helper], namespace
        else:
            py = helper
            if py.__module__ == func.__module__:
                ns = namespace
            else:
                ns = dict(py.__globals__)
                foreign.add(inspect.getsourcefile(py))
        if py.__name__ in found and found[py.__name__][0] is not py:
            raise ValueError(f'two helpers named {py.__name__!r}')
        found[py.__name__] = (py, ns)
    return found, sorted(foreign)


def _build(func, helpers, nogil, inline='always'):
    import numba

    namespace = dict(func.__globals__)
    found, foreign = _helper_namespaces(func, helpers, namespace)
    built = {}
    for name, (py, ns) in found.items():
        # inlined in numba's IR by default: a helper that receives another helper as an
        # argument (as ``spencer.heun_substeps`` receives its z step) then calls it directly,
        # and the kernel holds no pointer to a Python object (which numba cannot cache)
        built[name] = numba.njit(inline=inline)(_rebind(py, ns))
    for ns in [namespace] + [ns for _, ns in found.values()]:
        ns.update(built)
    loop = _rebind(func, namespace)
    if foreign:
        digest = hashlib.sha256()
        for path in foreign:
            with open(path, 'rb') as fh:
                digest.update(fh.read())
        loop.__qualname__ = f'{loop.__qualname__}_src{digest.hexdigest()[:12]}'
    key = f'{func.__module__}.{func.__qualname__}'
    try:
        return numba.njit(cache=True, nogil=nogil)(loop)
    except RuntimeError as exc:     # numba found no writable cache folder
        _CACHE_ERRORS[key] = str(exc)
        return numba.njit(cache=False, nogil=nogil)(loop)


def kernel(func, helpers=(), nogil=False, inline='always'):
    """
    Return the compiled (numba, ``cache=True``) version of a plain-Python loop.

    Parameters
    ----------
    func : function
        Loop over scalars and numpy arrays in numba's nopython subset, defined at module level.
    helpers : sequence of str or function
        Functions that ``func`` calls (directly or through its helpers), compiled too and
        inlined: names of module-level functions of the same module (bound in the loop's
        namespace), or the functions themselves, of any module (each bound in its own
        module's namespace; the helpers of a foreign helper must be listed too).
    nogil : bool
        Release the GIL while the loop runs (threads may then run it side by side on
        disjoint data). A loop is compiled with one setting, the first one asked for.
    inline : {'always', 'never'}
        Inline the helpers in numba's IR (``'always'``: needed when a helper receives
        another as an argument) or compile each as a function of its own that the loop
        calls (``'never'``; LLVM still inlines the small ones). A branchy algorithm that
        calls one helper from many places (the scalar inverse:
        :func:`mr_damper_model.models.scalar_inverse.scalar_kernels`) compiles in seconds with
        ``'never'`` and in most of a minute with ``'always'``.

    Returns
    -------
    numba.core.registry.CPUDispatcher
        Compiled on the first call for each set of argument types (or loaded from the cache).

    """
    key = (func.__module__, func.__qualname__)
    with _LOCK:
        disp = _KERNELS.get(key)
        if disp is None:
            disp = _KERNELS[key] = _build(func, tuple(helpers), bool(nogil), inline)
    return disp


def cache_status():
    """
    Describe the kernels built so far and where their cache lives.

    Returns
    -------
    dict
        ``'module.loop'`` -> dict with ``cached`` (bool), ``cache_path`` (str or None),
        ``cache_hits`` and ``cache_misses`` (signatures loaded from the cache or compiled in this
        process) and ``error`` (why caching is off, or '').

    """
    out = {}
    with _LOCK:
        items = list(_KERNELS.items())
    for (module, name), disp in items:
        label = f'{module}.{name}'
        stats = disp.stats
        cached = label not in _CACHE_ERRORS
        out[label] = {'cached': cached,
                      'cache_path': stats.cache_path if cached else None,
                      'cache_hits': int(sum(stats.cache_hits.values())),
                      'cache_misses': int(sum(stats.cache_misses.values())),
                      'error': _CACHE_ERRORS.get(label, '')}
    return out

"""The fit of one window: options, seeds, and the child process that runs it (no ROS)."""
import os
import pickle
import subprocess
import sys

import numpy as np

from mr_damper_model.identification.identify import identify
from mr_damper_model.models.validity import check_model_parameters


def window_seed(seed, index):
    """
    Return the swarm seed of window ``index`` of a stream (in-order mode).

    Parameters
    ----------
    seed : int
        ``LiveConfig.seed``.
    index : int
        Window position ``m`` in its stream.

    Returns
    -------
    int
        A seed in ``[0, 2**32)`` that depends only on ``seed`` and ``index``
        (``numpy.random.SeedSequence``), so each window's swarm starts differently but the same
        window always starts the same way.

    """
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def fit_kwargs(config):
    """
    Return the keyword arguments of the :func:`identify` call of one window.

    Parameters
    ----------
    config : LiveConfig
        Live settings.

    Returns
    -------
    dict
        ``method``, ``unbounded``, ``seed``, ``swarm_size``, ``maxiter``, ``budget_s``.

    """
    return {'method': 'separable', 'unbounded': bool(config.unbounded),
            'seed': int(config.seed), 'swarm_size': int(config.swarm_size),
            'maxiter': int(config.maxiter) or None,
            'budget_s': float(config.budget_s) or None}


def fit_data(data, model, config, x0=None):
    """
    Fit one window's data: the same :func:`identify` call the offline tool makes.

    Parameters
    ----------
    data : DamperData
        Samples to fit.
    model : {'kwok', 'kwok-current'}
        Model.
    config : LiveConfig
        Settings (see :func:`fit_kwargs`).
    x0 : dict, optional
        Warm start.

    Returns
    -------
    IdentificationResult
        Result of ``identify(data, model, x0=x0, **fit_kwargs(config))`` (kwok-current with
        ``model_options={'i_ref_a': config.i_ref_a}``).

    """
    options = {'i_ref_a': float(config.i_ref_a)} if model == 'kwok-current' else None
    return identify(data, model, x0=x0, model_options=options, **fit_kwargs(config))


class FitProcess:
    """
    :func:`fit_data` in a child interpreter (callable with the same signature and result).

    A fit holds the GIL for most of its time; in a child process it cannot delay the thread that
    receives the 1 kHz measurements.  The child runs ``python -m mr_damper_model.live`` in its
    own session, so a Ctrl-C sent to the parent's process group does not reach it: the parent
    ends it with :meth:`close` (or the child ends when its stdin closes, also when the parent
    was killed).  Requests and results travel pickled over the child's stdin / stdout;
    exceptions are re-raised in the parent.

    Why not ``concurrent.futures.ProcessPoolExecutor``: tried (one worker, ``spawn`` context,
    SIGINT ignored in its initializer). The spawn start method runs the *parent's* main script
    again in the child to rebuild ``__main__``; a script without an ``if __name__ ==
    '__main__'`` guard that builds an identifier (a user's quick script, ``python -c``) then
    spawns recursively and fails with ``BrokenProcessPool`` at the first call (seen with a
    five-line script). ``fork`` would copy the node's DDS threads and locks. A dedicated
    ``python -m`` child depends on nothing of the caller, ends with its stdin, and can be
    killed alone when a fit outlives the shutdown.
    """

    def __init__(self):
        self._proc = None

    def _start(self):
        self._proc = subprocess.Popen([sys.executable, '-m', 'mr_damper_model.live'],
                                      stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                      start_new_session=True)

    def _call(self, request):
        if self._proc is None or self._proc.poll() is not None:
            self._start()
        proc = self._proc   # close() from another thread (shutdown) must not pull it away
        try:
            pickle.dump(request, proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            proc.stdin.flush()
            status, value = pickle.load(proc.stdout)
        except (EOFError, OSError, ValueError, pickle.UnpicklingError) as exc:
            self.close()
            raise RuntimeError(f'fit process failed ({type(exc).__name__}: {exc})') from None
        if status == 'error':
            raise value
        return value

    def alive(self):
        """Return True while the child runs (False before the first call or once it died)."""
        proc = self._proc
        return proc is not None and proc.poll() is None

    def warm_up(self):
        """Start the child and import the fitting code in it; return True."""
        return self._call('ping')

    def __call__(self, data, model, config, x0=None):
        """Run ``fit_data(data, model, config, x0=x0)`` in the child."""
        return self._call((data, model, config, x0))

    def close(self, wait_s=2.0):
        """End the child process (EOF on its stdin; killed if still there after ``wait_s``)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            proc.stdin.close()
            proc.wait(timeout=wait_s)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()


def _malloc_trim():
    """
    Return a function that gives freed heap memory back to the OS (glibc), or a no-op.

    Fits allocate and free many temporaries of varying sizes; without trimming the child's
    heap keeps the high-water mark of its fragments (measured: +7 MB over the first 400 fits,
    then flat in-process, but still growing after 6 minutes in the live suite). After each
    fit ``malloc_trim(0)`` returns what is free, so the child's memory follows its use.
    """
    try:
        import ctypes
        trim = ctypes.CDLL('libc.so.6').malloc_trim
    except (OSError, AttributeError):
        return lambda: None
    return lambda: trim(0)


def _serve():
    """Child side of :class:`FitProcess`: answer pickled requests until stdin closes."""
    out = os.fdopen(os.dup(1), 'wb')
    os.dup2(2, 1)            # anything printed goes to stderr, stdout carries results only
    # numpy, scipy and the models are loaded once, with this module
    trim = _malloc_trim()
    src = sys.stdin.buffer
    while True:
        try:
            request = pickle.load(src)
        except (EOFError, pickle.UnpicklingError, ValueError, OSError):
            # stdin closed, also in the middle of a request (the node's shutdown closes it
            # while a fit is being sent): the end, not an error (no traceback at the stop)
            return
        try:
            reply = ('ok', True if request == 'ping' else fit_data(*request))
        except Exception as exc:  # returned to the parent, which raises it
            reply = ('error', exc)
        pickle.dump(reply, out, protocol=pickle.HIGHEST_PROTOCOL)
        out.flush()
        trim()


def parameter_reason(model, params, unbounded, i_ref_a, pinned_fraction=None, exempt=()):
    """
    Check a set's values, in the identifier's words.

    :func:`~mr_damper_model.models.validity.check_model_parameters` (``pinned_fraction`` None:
    no pinned check; ``exempt``: names that may sit at a bound): '' or
    ``nonfinite_parameters`` / ``out_of_bounds:<names>`` / ``pinned:<names>``.
    """
    check = check_model_parameters(model, params, unbounded=unbounded, i_ref_a=i_ref_a,
                                   pinned_fraction=pinned_fraction, exempt=exempt)
    if check.reason == 'non_finite':
        return 'nonfinite_parameters'
    if check.reason == 'pinned_at_bound':
        return f'pinned:{",".join(check.names)}'
    if check.reason:
        return f'out_of_bounds:{",".join(check.names)}'
    return ''

"""
Messages lost and restarts of a run with car corners (``--corners``, ``--config full-car``).

Each corner's rig, identifier and car state are read back from the recording under its
namespace (:func:`~mr_damper_bringup.report.recording.read_recording` with ``namespace``), and
the single-car figures are made per corner with the same functions: the measurements its
identifier lost (:func:`~mr_damper_bringup.report.losses.messages_summary`: the samples in the
recorded stamp span, recorded or missing between recorded stamps, against what every life of
the identifier counted, so a restarted recorder or identifier does not hide a loss) and, per
restart of any node, the time that corner's car was in fail-safe and the measurements its
identifier lost in the restart's window (:func:`~mr_damper_bringup.report.losses.
restart_figures`).
"""
from pathlib import Path
import tempfile

from mr_damper_bringup.report.losses import attribute_losses, messages_summary, restart_figures
from mr_damper_bringup.report.recording import (MEAS_COLUMNS, read_recording, RECORDING,
                                                recording_state)
from mr_damper_common.recording.columnlog import ArrayLog, ColumnReader

#: The per-corner figures of a restart that are summed (measurements) or kept at their largest
#: (times) over the corners.
SUMMED = ('measurements_lost',)
LONGEST = ('failsafe_s', 'no_car_state_s')


def corner_losses(parts, corners, supervision, work=None, last_counts=None):
    """
    Return each corner's lost measurements and every restart's cost per corner.

    Parameters
    ----------
    parts : list of path
        The recording's files in order (``recorder.recording_parts``).
    corners : sequence of str
        The corner namespaces (``fl``, ``fr``, ...).
    supervision : dict
        The launcher's record (``restarts.json``: ``restarts``, ``gave_up``, ``policy``); node
        names of a corner are ``<corner>.<node>``.
    work : path, optional
        Folder for the streamed extracts (default: a temporary one).
    last_counts : dict, optional
        Corner -> its identifier's ``samples_received`` in the launcher's last status of it
        (:func:`losses.messages_summary`'s ``last_count``).

    Returns
    -------
    corners : dict
        Corner -> ``samples_lost`` (measurements its identifier lost, every life counted),
        ``samples_recorded`` (by every recorder part), ``samples_in_span`` (recorded plus the
        gaps between recorded stamps: what its rig published while recorded),
        ``samples_received`` (every life of its identifier), ``identifier_lives``,
        ``lost_at_restarts`` / ``lost_not_at_restarts`` (the loss split between the restarts'
        windows and the rest).
    restarts : list of dict
        The launcher's restart records, each with ``failsafe_s_by_corner``,
        ``no_car_state_s_by_corner``, ``measurements_lost_by_corner``, ``window_s``, and the
        totals ``measurements_lost`` (sum over the corners), ``failsafe_s`` and
        ``no_car_state_s`` (the longest corner).
    recording : dict
        How complete the recording is (``recording_state``).

    """
    from mr_damper_bringup.config import IDENT
    restarts = [dict(r) for r in supervision.get('restarts') or ()]
    deaths = [r['death_epoch_s'] for r in restarts if r.get('death_epoch_s') is not None]
    out = {}
    rec = {'parts': []}
    with tempfile.TemporaryDirectory(prefix='.corners_', dir=work) as tmp:
        for c in corners:
            folder = Path(tmp) / c
            folder.mkdir()
            starts = [r['restart_epoch_s'] for r in restarts if r['node'] == f'{c}.{IDENT}'
                      and r.get('restart_epoch_s') is not None]
            rec = read_recording(parts, folder, identifier_starts=starts, namespace=c,
                                 car_modes_from=min(deaths) - 1.0 if deaths else None)
            meas = (ColumnReader(folder / 'measurement') if rec['measurements_received']
                    else ArrayLog({k: [] for k in MEAS_COLUMNS}))
            lost, br = messages_summary(rec, None, (last_counts or {}).get(c))
            mine = restart_figures(supervision, rec, meas)
            attribute_losses(br, mine)
            out[c] = {'samples_lost': lost if 'note' not in br else None,
                      'samples_recorded': br['measurements_received_by_recorder'],
                      'samples_in_span': (br['measurements_received_by_recorder']
                                          + br['measurement_gaps_at_recorder']),
                      'samples_received': br.get('measurements_received_by_identifier'),
                      'identifier_lives': len(rec['identifier_lives']),
                      'lost_at_restarts': br.get('measurements_lost_at_restarts'),
                      'lost_not_at_restarts': br.get('measurements_lost_not_at_restarts')}
            for r, m in zip(restarts, mine):
                r.setdefault('window_s', m.get('window_s'))
                for key in SUMMED + LONGEST:
                    r.setdefault(f'{key}_by_corner', {})[c] = m.get(key)
    if not corners:
        # no corner read the parts (a vehicle run on shipped models): scan them for their state
        rec = {'parts': [_scanned(part) for part in parts]}
    for r in restarts:
        for key in SUMMED + LONGEST:
            got = [v for v in (r.get(f'{key}_by_corner') or {}).values() if v is not None]
            r[key] = (sum(got) if key in SUMMED else max(got)) if got else None
    return out, restarts, recording_state(rec)


def _scanned(part):
    """Return ``McapScan.summary`` of one part read to its end (no message decoded)."""
    from mr_damper_common.recording.mcap_scan import McapScan
    reader = McapScan(part)
    for _ in reader.messages(()):
        pass
    return reader.summary()


def add_corner_losses(summary, out, supervision):
    """
    Put the recording's figures into the summary of a corner run (in place; returns it).

    ``summary['corners'][corner]`` gets :func:`corner_losses`' figures (its ``samples_lost``
    replaces any other count), ``summary['restarts']`` every restart with its cost per corner,
    ``restart_counts``, ``gave_up`` and ``recording`` (how complete, its parts). Without a
    recording ``samples_lost`` is None, with a note.
    """
    from mr_damper_bringup.recorder import recording_parts
    parts = [f for _, f in recording_parts(Path(out) / RECORDING)]
    restarts = [dict(r) for r in supervision.get('restarts') or ()]
    if parts:
        seen = {c: d.get('samples_received') for c, d in summary['corners'].items()}
        losses, restarts, state = corner_losses(parts, list(summary['corners']), supervision,
                                                work=out, last_counts=seen)
        for c, d in losses.items():
            summary['corners'].setdefault(c, {}).update(d)
    else:
        state = recording_state({'parts': []})
        for d in summary['corners'].values():
            d['samples_lost'] = None
    counts = {}
    for r in restarts:
        counts[r['node']] = counts.get(r['node'], 0) + (r.get('restart_s') is not None)
    summary.update(restarts=restarts, restart_counts=counts, gave_up=supervision.get('gave_up'),
                   recording={'file': RECORDING, **state})
    return summary

"""
Make the README's figure ``docs/main_job.png`` from one run of the main job.

Usage::

    .venv/bin/python launch_scripts/make_main_job_figure.py [--duration 40] [--run DIR]
        [--out docs/main_job.png] [--height 480]

Runs the main job, ``bash launch_scripts/main.sh --duration 40 --out DIR`` (default
``runs/main_job_figure``; with ``--duration 0`` no run: the plots already in ``DIR`` are used),
and joins the run's three plots, ``hysteresis.png``, ``convergence.png`` and ``ride.png``
(``mr_damper_bringup.plots``), side by side into one PNG, each scaled to the same height
(``--height``, default 480 pixels). The suite's own outputs are unchanged.
"""
import argparse
from pathlib import Path
import subprocess
import sys

REPO = Path(__file__).resolve().parents[1]
PANELS = ('hysteresis.png', 'convergence.png', 'ride.png')


def join_side_by_side(paths, out, height=None, dpi=110):
    """
    Write the PNGs ``paths`` side by side into ``out``, scaled to one height.

    Parameters
    ----------
    paths : sequence of path-like
        The panels, left to right.
    out : path-like
        The PNG written.
    height : int, optional
        Height of ``out`` [pixels]; default the tallest panel's.
    dpi : float
        Resolution of ``out`` [dots per inch] (sets only the PNG's metadata).

    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt
    images = [mpimg.imread(str(p)) for p in paths]
    height = height or max(im.shape[0] for im in images)
    widths = [im.shape[1] * height / im.shape[0] for im in images]
    fig = plt.figure(figsize=(sum(widths) / dpi, height / dpi), dpi=dpi)
    left = 0.0
    for im, w in zip(images, widths):
        ax = fig.add_axes((left / sum(widths), 0.0, w / sum(widths), 1.0))
        ax.imshow(im, interpolation='antialiased')
        ax.set_axis_off()
        left += w
    fig.savefig(str(out), dpi=dpi)
    plt.close(fig)


def main(argv=None):
    """Run the main job (unless ``--duration 0``), join its plots; return the exit status."""
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    p.add_argument('--duration', type=float, default=40.0,
                   help='run time of the main job [s, wall clock] (default 40; 0: no run)')
    p.add_argument('--run', default=str(REPO / 'runs' / 'main_job_figure'),
                   help='the run\'s output folder (default runs/main_job_figure)')
    p.add_argument('--out', default=str(REPO / 'docs' / 'main_job.png'),
                   help='the joined PNG (default docs/main_job.png)')
    p.add_argument('--height', type=int, default=480,
                   help='height of the joined PNG [pixels] (default 480)')
    args = p.parse_args(argv)
    run = Path(args.run)
    if args.duration > 0:
        status = subprocess.call(['bash', str(REPO / 'launch_scripts' / 'main.sh'),
                                  '--duration', f'{args.duration:g}', '--out', str(run)])
        if status != 0:
            print(f'make_main_job_figure: the suite ended with status {status}', file=sys.stderr)
            return status
    missing = [name for name in PANELS if not (run / name).is_file()]
    if missing:
        print(f'make_main_job_figure: {run} has no {", ".join(missing)}', file=sys.stderr)
        return 2
    join_side_by_side([run / name for name in PANELS], args.out, args.height)
    print(f'figure: {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())

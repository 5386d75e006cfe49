"""
``render_mode='rgb_array'``: a side view of the car on the road (matplotlib, Agg canvas).

The road is drawn over the 4 m before and 8 m after the (front) wheel as the car meets it;
the wheels, the body and the suspension struts at their present heights. Vertical motion is
drawn :data:`EXAGGERATION` times larger than the horizontal scale so a few millimetres of
travel are visible. The full car is seen from its left side (``fl`` and ``rl`` wheels; the
body line at the left body points, so pitch and roll both show).
"""
import numpy as np

from mr_damper_gym.kernel import MI_HEAD

#: Vertical scale over horizontal.
EXAGGERATION = 5.0
#: Picture size [pixels].
WIDTH, HEIGHT = 480, 240


def _track(core, batch, k, road, lead_s):
    """Distance [m] and left-track height [m] around the car, ``lead_s`` ahead of the rear."""
    v = road.speed_m_s if np.isfinite(road.speed_m_s) else 10.0
    t = batch.clock[k, 0]
    s = np.linspace(-4.0, 8.0, 241)
    times = t + lead_s + s / v
    z = road.z if core.car == 'quarter' else road.z_left
    return s, np.interp(times, road.t, z)


def side_view(core, batch, k, road):
    """
    Draw car ``k`` of a batch on its road; return an RGB image (HEIGHT, WIDTH, 3) of uint8.

    Parameters
    ----------
    core : EnvCore
        The environment (car kind and geometry).
    batch : CarBatch
        The cars.
    k : int
        Which car.
    road : RoadProfile or TwoTrackRoad or None
        Its road (None before the first reset: an empty picture).

    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(WIDTH / 80, HEIGHT / 80), dpi=80)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(-4.0, 8.0)
    ax.set_ylim(-2.5, 3.5)          # the horizontal scale: wheels are round
    ax.set_axis_off()
    if road is not None:
        ex = EXAGGERATION
        m = core.model
        x = batch.x[k]
        if core.car == 'quarter':
            lead, wheels = 0.0, [(0.0, 0)]
            body_x = [-1.0, 1.0]
        else:
            p = core.params
            lead = road.delay_s
            wheels = [(0.0, 0), (-p.wheelbase, 2)]          # fl, rl seen from the left
            body_x = [0.9, -p.wheelbase - 0.9]
        s, z = _track(core, batch, k, road, lead)
        ax.fill_between(s, -2.5, ex * z, color='0.55')
        ax.plot(s, ex * z, color='0.2', lw=1.5)
        body_pts = []
        r_w = 0.3
        for xw, i in wheels:
            zu = x[_wheel_index(m, i)]
            zb = batch.obs[k, i] + zu              # the body point: travel above the wheel
            yw = r_w + ex * zu
            yb = 1.1 + ex * zb
            ax.add_patch(_circle(xw, yw, r_w))
            ax.plot([xw, xw], [yw, yb], color='tab:orange', lw=4)
            body_pts.append((xw, yb))
        if len(body_pts) == 1:
            (xw, yb), = body_pts
            ax.add_patch(_box(body_x[0], yb, body_x[1] - body_x[0], 0.5))
        else:
            (xf, yf), (xr, yr) = body_pts
            slope = (yf - yr) / (xf - xr)
            xs = np.array(body_x)
            ys = yr + slope * (xs - xr)
            ax.fill(np.r_[xs, xs[::-1]], np.r_[ys, ys[::-1] + 0.5], color='tab:blue',
                    alpha=0.8)
        t = batch.clock[k, 0]
        ax.text(-3.9, 3.35, f'{road.name}  t = {t:6.3f} s', fontsize=8, va='top')
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[:, :, :3].copy()


def _wheel_index(model, i):
    """Index of wheel ``i``'s height in the kernel's state vector."""
    return int(model.mi[MI_HEAD + 2 * model.nb + i])


def _circle(x, y, r):
    from matplotlib.patches import Circle
    return Circle((x, y), r, color='0.1')


def _box(x, y, w, h):
    from matplotlib.patches import Rectangle
    return Rectangle((x, y), w, h, color='tab:blue', alpha=0.8)

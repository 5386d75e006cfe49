"""
The compiled car step: N cars (quarter or full) advanced together, one control period a step.

One function, :func:`advance_cars`, compiled with numba through
:func:`mr_damper_model.models.compiled.kernel` (disk cache; the damper helpers it inlines are
the models' own: ``spencer.heun_substeps_lanes`` (``heun_substeps`` over the four corners'
plants side by side, with the tanh of ``spencer.tanh_lanes``) / ``z_step_rooted`` /
``z_roots`` / ``_row`` and ``kwok_current.kwok_current_force_scalar``). It mirrors, for
arrays of cars, the simulator's plain-Python step, and the tests prove the two agree to
round-off (``tests/gym_envs/test_kernel.py``):

- the car (:class:`quarter_car_sim.plant.quarter_car.QuarterCar` / :class:`quarter_car_sim.plant.
  dynamics.FullCar` ``_advance`` and ``_make_state``): the exact discretisation of the linear
  part per pattern of wheels in contact (the simulator's own ``discretise`` tables, built by
  :mod:`mr_damper_gym.model`), road heights first-order hold, damper forces held; then each
  plant stepped to its end-of-step travel and velocity;
- the plants (:mod:`mr_damper_model.models.plant`: ``SpencerPlant`` and ``KwokCurrentPlant``
  ``_step``, the driver's slew limit, the coil lag);
- the roads' sampling (``QuarterCar._road_at``, ``TwoTrackRoad._sample``);
- the ISO 2631-1 filters (``RunningRideMetrics.update``: second-order sections, transposed
  direct form II, the coefficients of ``ride_metrics.wk_sos`` / ``full_car.metrics.we_sos``);
- the sensors (``quarter_car_sim.plant.sensors.Sensor.sample`` and ``SensorSampler.step``: bias,
  random walk, noise, scale error, quantum, latency in whole periods, dropouts), with the
  random numbers drawn beforehand in numpy (:mod:`mr_damper_gym.batch`).

Array layouts (``mi``, ``mf``, the per-car arrays) are built and documented by
:class:`mr_damper_gym.model.CarModel`; the index constants below name their slots.
"""
import math

import numpy as np

from mr_damper_model.models import compiled
from mr_damper_model.models.kwok_current import _coefficients, kwok_current_force_scalar
from mr_damper_model.models.spencer import (_row, heun_substeps_lanes, substeps, tanh_lanes,
                                            z_roots, z_step_rooted)

# --- mi: the model's integers -------------------------------------------------------------
(MI_NC, MI_NB, MI_NX, MI_NW, MI_NSEC, MI_NS, MI_SUB, MI_NOBS_STATE, MI_NOBS, MI_SENS_LEN,
 MI_NSUMS) = range(11)
#: then the columns where each block of a car's row of S starts (:data:`S_BLOCKS`), then, in
#: order: qb (nb), vb (nb), zu (nc), vu (nc), wheel track (nc), wheel delayed (nc), sensor
#: kind (ns: 0 body accelerometer, 1 travel), sensor corner (ns), sensor latency in periods
#: (ns), sensor period in control periods (ns)
MI_S = 11
#: The blocks of a car's row of the state array S, in order: mechanical state (nx), damper
#: forces held (nc), clock (3), road (2: samples, front-axle lead [s]), current commands (nc),
#: plants (nc x PL_N), ISO filters (nw x nsec x 2), running sums, sensors (ns x sensor row),
#: observation (nobs), reward (1).
S_BLOCKS = ('x', 'f', 'clock', 'road', 'cmd', 'plant', 'filt', 'sums', 'sens', 'obs', 'reward')
(MI_SX, MI_SF, MI_SCLOCK, MI_SROAD, MI_SCMD, MI_SPLANT, MI_SFILT, MI_SSUMS, MI_SSENS, MI_SOBS,
 MI_SREW) = range(MI_S, MI_S + len(S_BLOCKS))
MI_HEAD = MI_S + len(S_BLOCKS)

# --- mf: the model's floats ---------------------------------------------------------------
MF_DT, MF_H, MF_ROAD_DT, MF_A0, MF_T0, MF_RHO, MF_IMIN, MF_IMAX, MF_KT, MF_CT = range(10)
#: then, in order: T (nc x nb), Ks (nc x nc), c_s (nc), W (nc), m_u (nc), 1/M body (nb),
#: channel map Cw (nw x nb), axis factors (nw), sos (nw x nsec x 6), sensors (ns x N_SENS_F),
#: observation low (nobs), observation high (nobs), plant rows (nc x PP_N)
MF_HEAD = 10

#: per sensor floats: noise std, random-walk scale [unit/sqrt(s)], drift [unit/s], scale
#: error, offset, quantum, loss probability, hold mode (1: a lost sample repeats the last)
N_SENS_F = 8

# --- plant rows (the end of mf: nc x PP_N) -------------------------------------------------
#: kind (0 Spencer, 1 kwok-current), slew [A/s] (inf: none), max sub-step [s] (Spencer) or
#: coil time constant [s] (kwok), y0 [m] (Spencer; nan: the first travel) or 1 / i_ref [1/A]
#: (kwok), then the model's parameters (13 Spencer, 10 kwok-current)
PP_KIND, PP_SLEW, PP_SUB_OR_TAU, PP_Y0_OR_IREF, PP_PARAMS = range(5)
PP_N = PP_PARAMS + 13
#: constants of a Spencer plant's step (per corner, computed once a call): sub-steps, sub-step
#: [s], coil decay over a sub-step, then its ``z_roots`` (6)
SC_M, SC_H, SC_DECAY, SC_ROOTS = range(4)
SC_N = SC_ROOTS + 6

# --- per-car blocks of S ------------------------------------------------------------------
#: clock (3): time [s], control steps since reset, sensor samples since reset
CL_T, CL_STEPS, CL_SAMPLES = range(3)
#: road (2): samples of the tracks, time the front axle is ahead [s]
RD_N, RD_DELAY = range(2)
#: plant (nc x PL_N): Spencer y, z, u; kwok current in PL_U; previous piston travel and
#: velocity; the driver's output; started (0/1)
PL_Y, PL_Z, PL_U, PL_X, PL_V, PL_DRIVE, PL_STARTED = range(7)
PL_N = 7
#: sensor row (SE_BUF + largest latency + 1): turn-on bias, random walk, started, last
#: reading, held reading (observation), fresh (0/1), then the ring of readings in flight
SE_BIAS, SE_RW, SE_STARTED, SE_LAST, SE_HELD, SE_FRESH = range(6)
SE_BUF = 6
#: draws (N, B, ns, 3): random-walk normal, noise normal, loss uniform of each sample (a
#: car's numbers of one sample side by side in memory)
DR_RW, DR_NOISE, DR_LOSS = range(3)


def sum_slots(nw, nc, nb):
    """
    Return the offsets of the running sums of one car (``sums`` row): a dict and the length.

    ``ch`` (3 nw: sum aw^2, sum aw^4, peak |aw| per weighted channel), ``tyre`` (3 nc: sum of
    the squared dynamic load ratio, its peak, samples off the road), ``corner`` (3 nc: sum of
    travel^2, peak |travel|, sum of the current command), ``raw`` (nb: sum of the squared
    body accelerations), ``n`` (samples), ``clipped`` (observation entries clipped to the
    space), ``reward`` (sum of the rewards).
    """
    off = {'ch': 0, 'tyre': 3 * nw, 'corner': 3 * nw + 3 * nc, 'raw': 3 * nw + 6 * nc}
    off['n'] = off['raw'] + nb
    off['clipped'] = off['n'] + 1
    off['reward'] = off['n'] + 2
    return off, off['n'] + 3


def _road_sample(road, k, row, n, rdt, s):
    """Height and velocity of track ``row`` of car ``k`` at track time ``s`` (held at ends)."""
    u = s / rdt
    if u <= 0.0:
        return road[k, 2 * row, 0], 0.0
    j = int(u)
    if j >= n - 1:
        return road[k, 2 * row, n - 1], 0.0
    a = u - j
    z0 = road[k, 2 * row, j]
    d0 = road[k, 2 * row + 1, j]
    return (z0 + a * (road[k, 2 * row, j + 1] - z0),
            d0 + a * (road[k, 2 * row + 1, j + 1] - d0))


def _road_at(road, road_meta, k, t, track, delayed, rdt, zr, zd):
    """Road heights ``zr`` and velocities ``zd`` under every wheel of car ``k`` at ``t``."""
    n = int(road_meta[k, RD_N])
    delay = road_meta[k, RD_DELAY]
    for i in range(zr.shape[0]):
        s = t + delay if delayed[i] else t
        zr[i], zd[i] = _road_sample(road, k, track[i], n, rdt, s)


def _spencer_constants(pp, h, sc):
    """
    Write the constants of each Spencer plant's step over ``h`` in ``sc`` (once a call).

    Return 1 when every corner's plant is a Spencer one with the same sub-steps (one group of
    lanes for :func:`spencer.heun_substeps_lanes`), else 0.
    """
    same = 1
    for i in range(pp.shape[0]):
        if pp[i, PP_KIND] != 0.0:
            same = 0
            continue
        p = _row(pp[:, PP_PARAMS:], i)
        m = substeps(h, pp[i, PP_SUB_OR_TAU])
        hs = h / m
        sc[i, SC_M] = m
        sc[i, SC_H] = hs
        sc[i, SC_DECAY] = math.exp(-p[12] * hs)
        zc = z_roots(p[11], p[10], p[9])
        for j in range(6):
            sc[i, SC_ROOTS + j] = zc[j]
        if sc[i, SC_M] != sc[0, SC_M]:
            same = 0
    return same


def _plants_step(pp, sc, same, plant, k, h, travel, vrel, cmd, f, ps):
    """
    Step the plants of car ``k`` over ``h`` to (travel, vrel); their forces on the body in f.

    The Spencer plants' sub-steps run as lanes (:func:`spencer.heun_substeps_lanes`: each
    lane's arithmetic that of ``heun_substeps`` but for its own tanh, within about an ulp of
    the C library's), all corners together when ``same`` (:func:`_spencer_constants`), else
    corner by corner.
    """
    nc = pp.shape[0]
    for i in range(nc):
        st = plant[k, i * PL_N:(i + 1) * PL_N]
        xb = travel[i]
        vb = vrel[i]
        slew = pp[i, PP_SLEW]
        if st[PL_STARTED] == 0.0 and pp[i, PP_KIND] == 0.0:
            y0 = pp[i, PP_Y0_OR_IREF]
            st[PL_Y] = xb if y0 != y0 else y0
            st[PL_Z] = 0.0
            st[PL_X] = xb
            st[PL_V] = vb
        st[PL_STARTED] = 1.0
        if slew == math.inf:
            st[PL_DRIVE] = cmd[k, i]
        else:
            d = cmd[k, i] - st[PL_DRIVE]
            lim = slew * h
            if d > lim:
                d = lim
            elif d < -lim:
                d = -lim
            st[PL_DRIVE] += d
        drive = st[PL_DRIVE]
        if pp[i, PP_KIND] == 0.0:
            m = sc[i, SC_M]
            ps[i, 0] = (xb - st[PL_X]) / m
            ps[i, 1] = (vb - st[PL_V]) / m
            continue
        tau = pp[i, PP_SUB_OR_TAU]
        if tau > 0.0:
            st[PL_U] = drive + (st[PL_U] - drive) * math.exp(-h / tau)
        else:
            st[PL_U] = drive
        q = pp[i, PP_PARAMS:]
        f[k, i] = -kwok_current_force_scalar((q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7],
                                              q[8], q[9]), st[PL_U] * pp[i, PP_Y0_OR_IREF],
                                             xb, vb)
    row = plant[k]
    w = ps[:, 2:]
    for i in range(nc if same == 0 else 1):
        if same == 0 and pp[i, PP_KIND] != 0.0:
            continue
        a, b = (0, nc) if same else (i, i + 1)
        # the lanes' state: plant columns of car k (strided views), advanced in place
        heun_substeps_lanes(z_step_rooted, sc[a:b, SC_ROOTS:SC_ROOTS + 6],
                            pp[a:b, PP_PARAMS:], sc[a:b, SC_H], sc[a:b, SC_DECAY],
                            int(sc[a, SC_M]), row[a * PL_N + PL_Y:b * PL_N:PL_N],
                            row[a * PL_N + PL_Z:b * PL_N:PL_N], row[a * PL_N + PL_U:b * PL_N:PL_N],
                            row[a * PL_N + PL_X:b * PL_N:PL_N], row[a * PL_N + PL_V:b * PL_N:PL_N],
                            ps[a:b, 0], ps[a:b, 1], row[a * PL_N + PL_DRIVE:b * PL_N:PL_N],
                            w[a:b])
    for i in range(nc):
        if pp[i, PP_KIND] != 0.0:
            continue
        st = plant[k, i * PL_N:(i + 1) * PL_N]
        xb = travel[i]
        vb = vrel[i]
        st[PL_X], st[PL_V] = xb, vb
        c0a, c0b, k0, c1a, c1b, k1, x0, aa, ab, gamma, beta, A, eta = _row(pp[:, PP_PARAMS:], i)
        u = st[PL_U]
        c1 = c1a + c1b * u
        yd = ((aa + ab * u) * st[PL_Z] + (c0a + c0b * u) * vb + k0 * (xb - st[PL_Y])) / (
            c0a + c0b * u + c1)
        f[k, i] = -(c1 * yd + k1 * (xb - x0))


def _corner_motion(k, x, T, qb, vb, zu, vu, travel, vrel, body_v):
    """Suspension travel and velocity and the body point's velocity at each corner of car k."""
    nc, nb = T.shape
    for i in range(nc):
        pos = 0.0
        vel = 0.0
        for j in range(nb):
            pos += T[i, j] * x[k, qb[j]]
            vel += T[i, j] * x[k, vb[j]]
        travel[i] = pos - x[k, zu[i]]
        vrel[i] = vel - x[k, vu[i]]
        body_v[i] = vel


def _outputs(k, x, f, T, Ks, cs, W, minv_b, kt, ct, qb, vb, zu, vu, zr, zd, travel, vrel,
             tyre, acc_b, body_v, body_a):
    """Travel, rates, tyre loads and accelerations of car ``k`` now (``_make_state``)."""
    nc, nb = T.shape
    _corner_motion(k, x, T, qb, vb, zu, vu, travel, vrel, body_v)
    for i in range(nc):
        ft = W[i] + kt * (zr[i] - x[k, zu[i]]) + ct * (zd[i] - x[k, vu[i]])
        tyre[i] = ft if ft > 0.0 else 0.0
    for i in range(nc):
        s = 0.0
        for j in range(nc):
            s += Ks[i, j] * travel[j]
        body_a[i] = f[k, i] - s - cs[i] * vrel[i]      # the force on the body, for now
    for j in range(nb):
        s = 0.0
        for i in range(nc):
            s += T[i, j] * body_a[i]
        acc_b[j] = minv_b[j] * s
    for i in range(nc):
        s = 0.0
        for j in range(nb):
            s += T[i, j] * acc_b[j]
        body_a[i] = s


def _sense(k, clock, sens, sf, kind, corner, lat, period, draws, body_a, travel):
    """Sample the sensors of car ``k`` on its present state; deliver what arrives now."""
    idx = int(clock[k, CL_SAMPLES])
    col = idx % draws.shape[1]
    t = clock[k, CL_T]
    ns = kind.shape[0]
    length = sens.shape[1] // ns
    for s in range(ns):
        st = s * length             # car k's row of sensor s starts at sens[k, st]
        nbuf = lat[s] + 1
        if idx % period[s] == 0:
            x = body_a[corner[s]] if kind[s] == 0 else travel[corner[s]]
            noise_std, rw_scale, drift, scale, offset, quantum, p_loss, hold = (
                sf[s, 0], sf[s, 1], sf[s, 2], sf[s, 3], sf[s, 4], sf[s, 5], sf[s, 6], sf[s, 7])
            if sens[k, st + SE_STARTED] != 0.0 and rw_scale > 0.0:
                sens[k, st + SE_RW] += rw_scale * draws[k, col, s, DR_RW]
            sens[k, st + SE_STARTED] = 1.0
            bias = sens[k, st + SE_BIAS] + drift * t + sens[k, st + SE_RW]
            noise = noise_std * draws[k, col, s, DR_NOISE] if noise_std > 0.0 else 0.0
            lost = p_loss > 0.0 and draws[k, col, s, DR_LOSS] < p_loss
            y = (1.0 + scale) * (x + offset) + bias + noise
            if quantum > 0.0:
                y = quantum * np.round(y / quantum)
            if lost:
                y = sens[k, st + SE_LAST] if hold != 0.0 else math.nan
            else:
                sens[k, st + SE_LAST] = y
        else:
            y = math.inf            # nothing sampled at this step
        sens[k, st + SE_BUF + idx % nbuf] = y
        # the reading sampled lat[s] calls ago (SensorSampler's queue); inf: none yet
        got = sens[k, st + SE_BUF + (idx + 1) % nbuf] if idx >= lat[s] else math.inf
        if math.isfinite(got):
            sens[k, st + SE_HELD] = got
            sens[k, st + SE_FRESH] = 1.0
        else:
            sens[k, st + SE_FRESH] = 0.0
    clock[k, CL_SAMPLES] = idx + 1


def _record(k, sums, filt, sos, Cw, kw, acc_b, tyre, W, travel, cmd, a0, t0, rho, rew):
    """Feed the ISO filters and the running sums with car ``k``'s present sample."""
    nw, nsec = sos.shape[0], sos.shape[1]
    nb = acc_b.shape[0]
    nc = tyre.shape[0]
    comfort = 0.0
    for j in range(nw):
        y = 0.0
        for b in range(nb):
            y += Cw[j, b] * acc_b[b]
        for q in range(nsec):
            b0, b1, b2 = sos[j, q, 0], sos[j, q, 1], sos[j, q, 2]
            a1, a2 = sos[j, q, 4], sos[j, q, 5]
            c = 2 * (j * nsec + q)
            out = b0 * y + filt[k, c]
            filt[k, c] = b1 * y - a1 * out + filt[k, c + 1]
            filt[k, c + 1] = b2 * y - a2 * out
            y = out
        y2 = y * y
        sums[k, 3 * j] += y2
        sums[k, 3 * j + 1] += y2 * y2
        if abs(y) > sums[k, 3 * j + 2]:
            sums[k, 3 * j + 2] = abs(y)
        comfort += kw[j] * kw[j] * y2
    o = 3 * nw
    tyre_sq = 0.0
    for i in range(nc):
        dyn = (tyre[i] - W[i]) / W[i]
        sums[k, o + 3 * i] += dyn * dyn
        if abs(dyn) > sums[k, o + 3 * i + 1]:
            sums[k, o + 3 * i + 1] = abs(dyn)
        if tyre[i] <= 0.0:
            sums[k, o + 3 * i + 2] += 1.0
        tyre_sq += dyn * dyn
    o += 3 * nc
    for i in range(nc):
        sums[k, o + 3 * i] += travel[i] * travel[i]
        if abs(travel[i]) > sums[k, o + 3 * i + 1]:
            sums[k, o + 3 * i + 1] = abs(travel[i])
        sums[k, o + 3 * i + 2] += cmd[k, i]
    o += 3 * nc
    for b in range(nb):
        sums[k, o + b] += acc_b[b] * acc_b[b]
    o += nb
    sums[k, o] += 1.0
    r = -(comfort / a0 + rho * (tyre_sq / nc) / t0) / (1.0 + rho)
    sums[k, o + 2] += r
    rew[k] = r


def _observe(k, obs, lo, hi, nobs_state, sums, clip_slot, x, f, plant, sens, cmd, qb, vb,
             zu, vu, zr, travel, vrel, body_v, body_a, acc_b):
    """Write car ``k``'s observation row (true state, then sensors), clipped to the space."""
    nc = travel.shape[0]
    nb = acc_b.shape[0]
    row = obs[k]
    for i in range(nc):
        row[i] = travel[i]
        row[nc + i] = x[k, zu[i]] - zr[i]
        row[2 * nc + i] = vrel[i]
        row[3 * nc + i] = body_v[i]
        row[4 * nc + i] = body_a[i]
        row[5 * nc + i] = x[k, vu[i]]
        row[6 * nc + i] = f[k, i]
        row[7 * nc + i] = plant[k, i * PL_N + PL_U]
        row[8 * nc + i] = cmd[k, i]
    o = 9 * nc
    if nb > 1:
        mean_road = 0.0
        for i in range(nc):
            mean_road += zr[i]
        row[o] = x[k, qb[0]] - mean_road / nc
        for j in range(1, nb):
            row[o + j] = x[k, qb[j]]
        for j in range(nb):
            row[o + nb + j] = x[k, vb[j]]
            row[o + 2 * nb + j] = acc_b[j]
    o = nobs_state
    ns = (row.shape[0] - nobs_state - nc) // 2
    length = sens.shape[1] // ns if ns else 0
    for s in range(ns):
        row[o + s] = sens[k, s * length + SE_HELD]
        row[o + ns + s] = sens[k, s * length + SE_FRESH]
    for i in range(nc):
        row[o + 2 * ns + i] = cmd[k, i]
    for j in range(row.shape[0]):
        v = row[j]
        if v < lo[j]:
            row[j] = lo[j]
            sums[k, clip_slot] += 1.0
        elif v > hi[j]:
            row[j] = hi[j]
            sums[k, clip_slot] += 1.0


def _advance_cars(nsteps, record_first, record, sense, active, G, mf, mi, S, road, draws):
    """
    Advance the active cars ``nsteps`` control periods with their commands held.

    Parameters
    ----------
    nsteps : int
        Control periods (0: only record the present sample and observe).
    record_first : int
        1: feed the present sample to the ISO filters and sums before stepping.
    record : int
        1: feed every new sample (and set the reward).
    sense : int
        1: sample the sensors after each period.
    active : ndarray (N,) of uint8
        Cars to advance.
    G, mf, mi
        The model (:class:`mr_damper_gym.model.CarModel`).
    S : ndarray (N, width)
        The cars' rows (:data:`S_BLOCKS`; :class:`mr_damper_gym.batch.CarBatch`), changed in
        place: commands in, state, sums, observation and reward out.
    road : ndarray (N, 2 tracks, samples)
        Each car's tracks: height [m] and vertical velocity [m/s] rows.
    draws : ndarray (N, B, ns, 3)
        Each car's sensor random numbers of its present block.

    """
    nc, nb, nx = mi[MI_NC], mi[MI_NB], mi[MI_NX]
    nw, nsec, ns, nsub = mi[MI_NW], mi[MI_NSEC], mi[MI_NS], mi[MI_SUB]
    nobs_state, nobs = mi[MI_NOBS_STATE], mi[MI_NOBS]
    x = S[:, mi[MI_SX]:mi[MI_SX] + nx]
    f = S[:, mi[MI_SF]:mi[MI_SF] + nc]
    clock = S[:, mi[MI_SCLOCK]:mi[MI_SCLOCK] + 3]
    road_meta = S[:, mi[MI_SROAD]:mi[MI_SROAD] + 2]
    cmd = S[:, mi[MI_SCMD]:mi[MI_SCMD] + nc]
    plant = S[:, mi[MI_SPLANT]:mi[MI_SPLANT] + nc * PL_N]
    filt = S[:, mi[MI_SFILT]:mi[MI_SFILT] + nw * nsec * 2]
    sums = S[:, mi[MI_SSUMS]:mi[MI_SSUMS] + mi[MI_NSUMS]]
    sens = S[:, mi[MI_SSENS]:mi[MI_SSENS] + ns * mi[MI_SENS_LEN]]
    obs = S[:, mi[MI_SOBS]:mi[MI_SOBS] + nobs]
    rew = S[:, mi[MI_SREW]]
    o = MI_HEAD
    qb = mi[o:o + nb]
    vb = mi[o + nb:o + 2 * nb]
    o += 2 * nb
    zu = mi[o:o + nc]
    vu = mi[o + nc:o + 2 * nc]
    track = mi[o + 2 * nc:o + 3 * nc]
    delayed = mi[o + 3 * nc:o + 4 * nc]
    o += 4 * nc
    kind = mi[o:o + ns]
    corner = mi[o + ns:o + 2 * ns]
    lat = mi[o + 2 * ns:o + 3 * ns]
    period = mi[o + 3 * ns:o + 4 * ns]
    h, rdt = mf[MF_H], mf[MF_ROAD_DT]
    a0, t0, rho = mf[MF_A0], mf[MF_T0], mf[MF_RHO]
    kt, ct = mf[MF_KT], mf[MF_CT]
    o = MF_HEAD
    T = mf[o:o + nc * nb].reshape((nc, nb))
    o += nc * nb
    Ks = mf[o:o + nc * nc].reshape((nc, nc))
    o += nc * nc
    cs = mf[o:o + nc]
    W = mf[o + nc:o + 2 * nc]
    o += 3 * nc
    minv_b = mf[o:o + nb]
    o += nb
    Cw = mf[o:o + nw * nb].reshape((nw, nb))
    o += nw * nb
    kw = mf[o:o + nw]
    o += nw
    sos = mf[o:o + nw * nsec * 6].reshape((nw, nsec, 6))
    o += nw * nsec * 6
    sf = mf[o:o + ns * N_SENS_F].reshape((ns, N_SENS_F))
    o += ns * N_SENS_F
    lo = mf[o:o + nobs]
    hi = mf[o + nobs:o + 2 * nobs]
    o += 2 * nobs
    pp = mf[o:o + nc * PP_N].reshape((nc, PP_N))
    clip_slot = 3 * nw + 6 * nc + nb + 1          # sum_slots(nw, nc, nb)['clipped']
    ncol = G.shape[2]
    # each car's scratch: its own row (a call's own array: calls on other cars may run at the
    # same time in other threads, the GIL released)
    # the call's scratch (one car at a time; calls on other cars may run at the same time in
    # other threads, the GIL released): sliced once a call, as a slice costs numba two atomic
    # reference counts
    work = np.empty(ncol + nx + 19 * nc + nb)
    vec, xn, rest = work[:ncol], work[ncol:ncol + nx], work[ncol + nx:]
    sc = np.zeros((nc, SC_N))
    same = _spencer_constants(pp, h, sc)
    for k in range(x.shape[0]):
        if not active[k]:
            continue
        # grouped: CPython passes a call of more than 30 arguments as *args, which numba's
        # inliner refuses
        _advance_car(k, nsteps, record_first, record, sense, G,
                     (h, rdt, a0, t0, rho, kt, ct), (nsub, nobs_state, clip_slot, same),
                     (T, Ks, cs, W, minv_b, Cw, kw, sos, sf, lo, hi, pp, sc),
                     (qb, vb, zu, vu, track, delayed, kind, corner, lat, period),
                     (x, f, clock, road_meta, cmd, plant, filt, sums, sens, obs, rew), road,
                     draws, vec, xn, rest)
    return 0


def _advance_car(k, nsteps, record_first, record, sense, G, scalars, counts, model, index,
                 car, road, draws, vec, xn, rest):
    """Advance car ``k`` (the body of :func:`_advance_cars`'s loop; scratch in its own row)."""
    h, rdt, a0, t0, rho, kt, ct = scalars
    nsub, nobs_state, clip_slot, same = counts
    T, Ks, cs, W, minv_b, Cw, kw, sos, sf, lo, hi, pp, sc = model
    qb, vb, zu, vu, track, delayed, kind, corner, lat, period = index
    x, f, clock, road_meta, cmd, plant, filt, sums, sens, obs, rew = car
    nc, nb = T.shape
    nx = xn.shape[0]
    ncol = vec.shape[0]
    vec[ncol - 1] = 1.0
    zr0, zd0, zr1, zd1 = rest[:nc], rest[nc:2 * nc], rest[2 * nc:3 * nc], rest[3 * nc:4 * nc]
    travel, vrel, tyre = rest[4 * nc:5 * nc], rest[5 * nc:6 * nc], rest[6 * nc:7 * nc]
    body_v, body_a = rest[7 * nc:8 * nc], rest[8 * nc:9 * nc]
    acc_b = rest[9 * nc:9 * nc + nb]
    ps = rest[9 * nc + nb:19 * nc + nb].reshape((nc, 10))
    t = clock[k, CL_T]
    _road_at(road, road_meta, k, t, track, delayed, rdt, zr0, zd0)
    if record_first or nsteps == 0:
        _outputs(k, x, f, T, Ks, cs, W, minv_b, kt, ct, qb, vb, zu, vu, zr0, zd0, travel,
                 vrel, tyre, acc_b, body_v, body_a)
    if record_first:
        _record(k, sums, filt, sos, Cw, kw, acc_b, tyre, W, travel, cmd, a0, t0, rho, rew)
    for _ in range(nsteps):
        for _ in range(nsub):
            t1 = t + h
            _road_at(road, road_meta, k, t1, track, delayed, rdt, zr1, zd1)
            pattern = 0
            for i in range(nc):
                if W[i] + kt * (zr0[i] - x[k, zu[i]]) + ct * (zd0[i] - x[k, vu[i]]) > 0.0:
                    pattern += 1 << i
            for j in range(nx):
                vec[j] = x[k, j]
            for i in range(nc):
                vec[nx + i] = zr0[i]
                vec[nx + nc + i] = zr1[i]
                vec[nx + 2 * nc + i] = (zr1[i] - zr0[i]) / h
                vec[nx + 3 * nc + i] = f[k, i]
            g = G[pattern]
            for r in range(nx):
                acc = 0.0
                for j in range(ncol):
                    acc += g[r, j] * vec[j]
                xn[r] = acc
            for j in range(nx):
                x[k, j] = xn[j]
            _corner_motion(k, x, T, qb, vb, zu, vu, travel, vrel, body_v)
            _plants_step(pp, sc, same, plant, k, h, travel, vrel, cmd, f, ps)
            t = t1
            for i in range(nc):
                zr0[i] = zr1[i]
                zd0[i] = zd1[i]
        clock[k, CL_T] = t
        clock[k, CL_STEPS] += 1.0
        _outputs(k, x, f, T, Ks, cs, W, minv_b, kt, ct, qb, vb, zu, vu, zr0, zd0, travel, vrel,
                 tyre, acc_b, body_v, body_a)
        if sense:
            _sense(k, clock, sens, sf, kind, corner, lat, period, draws, body_a, travel)
        if record:
            _record(k, sums, filt, sos, Cw, kw, acc_b, tyre, W, travel, cmd, a0, t0, rho, rew)
    _observe(k, obs, lo, hi, nobs_state, sums, clip_slot, x, f, plant, sens, cmd, qb, vb, zu,
             vu, zr0, travel, vrel, body_v, body_a, acc_b)


#: Functions the compiled step inlines (this module's, then the models' own).
HELPERS = ('_advance_car', '_road_sample', '_road_at', '_spencer_constants', '_plants_step',
           '_corner_motion', '_outputs', '_sense', '_record', '_observe', _row,
           heun_substeps_lanes, substeps, tanh_lanes, z_roots, z_step_rooted,
           kwok_current_force_scalar, _coefficients)


def compiled_step():
    """
    Return the compiled :func:`_advance_cars` (compiled on first use, cached on disk).

    It releases the GIL: threads may step disjoint sets of cars of one batch side by side.
    """
    return compiled.kernel(_advance_cars, helpers=HELPERS, nogil=True)

"""Friction and restitution from a ``drop`` run (CONTRACTS.md section 4).

Model (SI; docs/flights.md).  The mass falls from rest at height ``h`` under Coulomb
friction ``mu`` (a fraction of its weight) on the guide: effective gravity ``g(1-mu)``
going down, ``g(1+mu)`` going up.  Hence

* first fall, release to first contact: ``t0 = sqrt(2 h / (g (1 - mu)))``, impact speed
  ``v_in = g (1 - mu) t0``;
* a flight that starts with upward speed ``v`` lasts
  ``F(v) = v / (g (1 + mu)) + v / (g sqrt(1 - mu^2))`` and lands with speed
  ``v sqrt((1 - mu) / (1 + mu))``;
* each impact returns ``e`` times the impact speed, so the n-th flight (n = 1, 2, ...)
  has ``v_n = e v_in r^(n-1)`` with ``r = e sqrt((1 - mu) / (1 + mu))``, the ratio of
  successive flights.

The fall time and the bounce flights are fitted jointly by least squares in seconds
(each measured time counts equally; the timing error is the same for all).  95 %
intervals come from a residual bootstrap: the fitted times plus residuals drawn with
replacement (seeded), refitted ``n_boot`` times, 2.5th and 97.5th percentiles.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from bouncelab.errors import BouncelabError, collected_warnings

G_STANDARD = 9.80665  # m/s^2
MIN_FLIGHT_S = 2e-3  # shorter flights: chatter, where contact compliance matters
MIN_BOUNCES = 2  # the fall and two flights: mu and e with one degree of freedom left
CHECKED_BOUNCES = 3  # ... and from three on, the bounces alone check release_t_s


def model_times(mu: float, e: float, h_m: float, n_flights: int, g: float = G_STANDARD):
    """Fall time and the first ``n_flights`` bounce flight times, s: shape (1 + n_flights,).

    ``mu`` fraction of the weight, ``e`` restitution, ``h_m`` drop height (m).
    """
    t0 = np.sqrt(2.0 * h_m / (g * (1.0 - mu)))
    v_in = g * (1.0 - mu) * t0
    r = e * np.sqrt((1.0 - mu) / (1.0 + mu))
    k = 1.0 / (g * (1.0 + mu)) + 1.0 / (g * np.sqrt(1.0 - mu * mu))
    v = e * v_in * r ** np.arange(n_flights)
    return np.concatenate([[t0], k * v])


def fit_drop(t_fall_s: float, flights_s: np.ndarray, h_m: float, g: float = G_STANDARD):
    """Least-squares ``(mu, e)`` and residuals (s) from a fall time and bounce flights.

    Parameters
    ----------
    t_fall_s : release to first contact, s.
    flights_s : (n,) successive bounce flight durations, s, first bounce first.
    h_m : drop height, m.  g : m/s^2.
    """
    data = np.concatenate([[t_fall_s], np.asarray(flights_s, dtype=np.float64)])
    n = data.size - 1
    # start: mu from the fall time alone, e from the ratio of the first two flights
    mu0 = float(np.clip(1.0 - 2.0 * h_m / (g * t_fall_s**2), 0.0, 0.9))
    r0 = float(np.clip(np.median(data[2:] / data[1:-1]), 0.05, 0.95)) if n >= 2 else 0.5
    e0 = float(np.clip(r0 / np.sqrt((1 - mu0) / (1 + mu0)), 0.05, 0.99))
    return _fit(data, h_m, g, (mu0, e0))


def _fit(data, h_m, g, x0):
    n = data.size - 1

    def resid(p):
        return model_times(p[0], p[1], h_m, n, g) - data

    sol = least_squares(
        resid, x0, bounds=([-0.2, 0.0], [0.95, 1.0]), x_scale=[0.1, 0.1], xtol=1e-12, ftol=1e-12
    )
    return float(sol.x[0]), float(sol.x[1]), resid(sol.x)


def bounce_sequence(t_fall_s, takeoff_s, landing_s, min_flight_s: float = MIN_FLIGHT_S):
    """The usable bounce flights after the first contact, s: shape (n,).

    Takes the flights in order from the first one, and stops at the first flight
    shorter than ``min_flight_s`` or not shorter than the bounce before it (the sequence
    of a free drop only shrinks; anything else is chatter, rest or a new disturbance).

    Flights shorter than ``min_flight_s`` followed, within ``min_flight_s`` of the first
    one's takeoff, by a flight of at least ``min_flight_s`` are part of an impact, not
    bounces, and are skipped: the contact chattering, or an RC tail longer than the
    contact read as contact, opening, contact again (a sound card's drop test at 44.1
    kHz, where too few clean edges exist to measure the RC). The bounce then starts where
    the impact's last contact ends.
    """
    ta = np.asarray(takeoff_s, dtype=np.float64)
    f = np.asarray(landing_s, dtype=np.float64) - ta
    out = []
    i = 0
    while i < f.size:
        if f[i] < min_flight_s:
            j = i + 1
            while j < f.size and f[j] < min_flight_s and ta[j] - ta[i] < min_flight_s:
                j += 1
            if j < f.size and f[j] >= min_flight_s and ta[j] - ta[i] < min_flight_s:
                i = j  # within an impact
                continue
            break
        if out and f[i] >= out[-1]:
            break
        out.append(f[i])
        i += 1
    return np.asarray(out)


#: A landing sooner after the release than this share of the free-fall time
#: ``sqrt(2 h / g)`` (friction only lengthens the fall) is not the mass: a spark.
MIN_FALL_SHARE = 0.8
#: A split is mended where merging two flights shrinks the scatter of the bounce
#: flights' logarithms about a geometric sequence by this factor, from at least
#: ``SPLIT_MIN_SCATTER`` (sum of squares; 0.003 is a flight 5 % off the sequence).
SPLIT_GAIN, SPLIT_MIN_SCATTER = 10.0, 0.003


def first_landing(landing_s, release_t_s: float, h_m: float, g: float = G_STANDARD):
    """Index of the first landing that can be the mass's, and the sooner ones' count.

    ``landing_s`` (n,) sorted contact starts, s. A contact sooner after ``release_t_s``
    than ``MIN_FALL_SHARE`` of the free fall ``sqrt(2 h / g)`` cannot be the mass's
    landing (friction only slows the fall; the share leaves room for a release time
    read a little late): an electrical spark, which otherwise was taken as the landing
    and the real bounces as too few. None when no landing qualifies.
    """
    landing_s = np.asarray(landing_s, dtype=np.float64)
    after = np.flatnonzero(landing_s > release_t_s)
    t_min = release_t_s + MIN_FALL_SHARE * np.sqrt(2.0 * h_m / g)
    ok = after[landing_s[after] >= t_min]
    if ok.size == 0:
        return None, int(after.size)
    return int(ok[0]), int(np.count_nonzero(landing_s[after] < t_min))


def _geometric_scatter(f: np.ndarray) -> float:
    """Sum of squared residuals of ``log f`` about its straight line in the bounce index
    (a free drop's flights shrink geometrically); 0 for fewer than three flights."""
    if f.size < 3:
        return 0.0
    n = np.arange(f.size, dtype=np.float64)
    y = np.log(f)
    coef = np.polyfit(n, y, 1)
    return float(np.sum((y - np.polyval(coef, n)) ** 2))


def mend_splits(takeoff_s, landing_s, n_first: int = 6):
    """Flights ``(takeoff_s, landing_s)`` with bounces split by a brief false contact
    joined again, and the number joined.

    A spark in a bounce's flight reads as a landing and a takeoff: the bounce becomes two
    shorter flights, and the fit took them for two bounces (a probe's drop test: 79.8 ms
    read as 39.8 and 40 ms, e 0.38 for 0.515, exit 0). Among the first ``n_first``
    flights, two neighbours are joined (the contact between them counted as flight)
    where that shrinks the scatter of the flights about a geometric sequence
    (:func:`_geometric_scatter`, over the flights up to the first shorter than
    ``MIN_FLIGHT_S``, which the bounce sequence uses) by ``SPLIT_GAIN`` from at least
    ``SPLIT_MIN_SCATTER``: joining two real bounces breaks the sequence instead, and the
    chatter after the last bounce is not judged (the compliant generator's 1.0 and 0.1
    ms flights were joined, harmlessly but with a warning). One pair at a time, best
    first.
    """
    ta = list(np.asarray(takeoff_s, dtype=np.float64))
    tl = list(np.asarray(landing_s, dtype=np.float64))
    joined = 0

    def scatter(f):  # over the flights the bounce sequence would use (>= 2 ms)
        short = np.flatnonzero(f < MIN_FLIGHT_S)
        return _geometric_scatter(f[: short[0]] if short.size else f)

    while True:
        m = min(n_first, len(ta))
        f = np.asarray(tl[:m]) - np.asarray(ta[:m])
        if f.size < 3 or np.any(f <= 0):
            break
        base = scatter(f)
        if base < SPLIT_MIN_SCATTER:
            break
        best, best_i = base / SPLIT_GAIN, None
        for i in range(m - 1):
            g = np.concatenate([f[:i], [tl[i + 1] - ta[i]], f[i + 2 :]])
            sc = scatter(g)
            if sc < best:
                best, best_i = sc, i
        if best_i is None:
            break
        tl[best_i] = tl[best_i + 1]
        del ta[best_i + 1], tl[best_i + 1]
        joined += 1
    return np.asarray(ta), np.asarray(tl), joined


#: A fall time this many standard errors away from what the bounces alone give is
#: warned about: a release time read off by a few milliseconds.
FALL_Z = 10.0
MU_PLAUSIBLE = -0.01  # ... only where the bounces alone give a friction no lower than this


def fall_from_bounces(flights_s, h_m: float, g: float = G_STANDARD, dt_s: float = 0.0):
    """What the bounce flights alone say: ``(mu, e, t_fall_s, t_fall_sd_s)``, or None.

    Given ``h_m``, the first flight and the flights' ratio fix ``mu`` and ``e`` without
    the fall time, so the fall the model then predicts checks ``release_t_s`` (entered by
    hand). Its standard error is the linearised least-squares one, from the residuals'
    spread (at least the timing resolution ``dt_s / sqrt(12)``). None with fewer than
    :data:`CHECKED_BOUNCES` flights (two fix the parameters and leave nothing to
    estimate an error from) or where the flights leave the two parameters unresolved.
    """
    fl = np.asarray(flights_s, dtype=np.float64)
    n = fl.size
    if n < CHECKED_BOUNCES:
        return None

    def model(p):
        return model_times(p[0], p[1], h_m, n, g)

    sol = least_squares(
        lambda p: model(p)[1:] - fl,
        (0.2, 0.5),
        bounds=([-0.2, 0.0], [0.95, 1.0]),
        x_scale=[0.1, 0.1],
        xtol=1e-12,
        ftol=1e-12,
    )
    p = sol.x
    step = 1e-6
    jac = np.stack(
        [(model(p + step * d) - model(p - step * d)) / (2 * step) for d in np.eye(2)], axis=1
    )
    jf, jt = jac[1:], jac[0]
    s2 = max(float(np.sum(sol.fun**2)) / max(n - 2, 1), dt_s**2 / 12.0)
    try:
        cov = s2 * np.linalg.inv(jf.T @ jf)
    except np.linalg.LinAlgError:
        return None
    var = float(jt @ cov @ jt)
    if not np.isfinite(var) or var < 0:
        return None
    return float(p[0]), float(p[1]), float(model(p)[0]), float(np.sqrt(var))


def bootstrap_ci(data, h_m, g, mu, e, resid, n_boot: int, seed: int, dt_s: float = 0.0):
    """95 % percentile intervals of (mu, e) from a residual bootstrap; shapes (2,), (2,).

    ``dt_s`` > 0 (the sample interval, s): each replicate also moves every edge by a
    uniform draw within its sample interval (the fall time has one edge, the release
    being a stated time; each flight two), from a generator of its own, so the residual
    draws are those of ``dt_s = 0``. Without it, a few bounces that fit to microseconds
    gave intervals a few 1e-4 wide that missed the truth by the half sample where an
    edge sits within its interval (a probe: mu 0.2897 [0.2897, 0.2898] for 0.29).
    """
    rng = np.random.default_rng(seed)
    jitter = np.random.default_rng([seed, 1])
    n = data.size
    fitted = data + resid
    # inflate residuals for the two fitted parameters (unbiased spread)
    r = (resid - resid.mean()) * np.sqrt(n / max(n - 2, 1))
    mus = np.empty(n_boot)
    es = np.empty(n_boot)
    for b in range(n_boot):
        star = fitted + rng.choice(r, size=n, replace=True)
        if dt_s > 0:
            u = jitter.uniform(-0.5 * dt_s, 0.5 * dt_s, size=(2, n))
            star = star + u[0] - np.concatenate(([0.0], u[1, 1:]))
        mus[b], es[b], _ = _fit(star, h_m, g, (mu, e))
    return np.percentile(mus, [2.5, 97.5]), np.percentile(es, [2.5, 97.5])


def calibrate_run(run_dir: str | Path, n_boot: int = 2000, seed: int = 0) -> dict:
    """Friction ``mu`` and restitution ``e`` of a drop run, with 95 % bootstrap intervals.

    Returns the CONTRACTS.md section 4 dict plus ``run`` (the drop run's id, so that a
    diagnosis and the report can say whose calibration they show), ``t_fall_s``,
    ``flights_s`` (the fitted bounce flights), ``residuals_s``, ``ratio`` (r),
    ``g_m_s2``, ``drop_height_m``, ``n_boot``, ``seed``, and what the bounces alone
    give (:func:`fall_from_bounces`: ``mu_from_bounces``, ``restitution_from_bounces``,
    ``t_fall_from_bounces_s`` and its standard error ``t_fall_from_bounces_sd_s``; a
    fall more than ``FALL_Z`` of them off is warned about), and ``warnings``: the lines
    logged while reading and fitting the drop (:func:`bouncelab.errors.collected_warnings`),
    so that the report can show them.

    Raises
    ------
    BouncelabError
        Not a drop run; no contact after the release; fewer than two bounces.
    """
    with collected_warnings() as warnings:
        out = _calibrate_run(run_dir, n_boot, seed)
    return out | {"warnings": list(warnings)}


def _calibrate_run(run_dir: str | Path, n_boot: int, seed: int) -> dict:
    """:func:`calibrate_run` without the collection of its warnings."""
    from bouncelab.flights.coupling import ac_coupling_tau, undo_ac_coupling
    from bouncelab.flights.detect import detect_contacts
    from bouncelab.flights.extract import _step_slice, sample_times
    from bouncelab.runs import load_run, read_recording

    run = load_run(run_dir)
    if run.kind != "drop":
        raise BouncelabError(
            run.yaml_path, f"calibrate needs a drop run (kind: drop); this run is a {run.kind}"
        )
    rec = read_recording(run, roles=("continuity",))
    fs = float(rec.fs)
    g = float(run.extra.get("g_m_s2", G_STANDARD) or G_STANDARD)
    h = float(run.drop_height_m)
    opened = [_step_slice(rec.t_start_s, run.release_t_s, fs, rec.time_s, rec.n_samples)]
    x = rec.channels["continuity"]
    tau_ac = ac_coupling_tau(x, fs)
    if tau_ac is not None:
        x = undo_ac_coupling(x, fs, tau_ac)
        logging.getLogger(__name__).warning(
            "%s: the continuity channel drains towards its mean as through an AC-coupled "
            "input (corner %.3g Hz): undone before the detection",
            rec.path,
            1.0 / (2.0 * np.pi * tau_ac),
        )
    det = detect_contacts(
        x,
        run.contact_level,
        (),
        opened,
        path=rec.path,
        sample_rate_hz=fs,
    )
    edges_s = sample_times(det.t_edge, fs, rec.time_s)
    landing = edges_s[det.kind == 1]
    first, n_sparks = first_landing(landing, run.release_t_s, h, g)
    if first is None:
        raise BouncelabError(rec.path, "no contact after release_t_s: the mass never lands")
    log = logging.getLogger(__name__)
    if n_sparks:
        log.warning(
            "%s: %d contact(s) sooner after release_t_s than %.0f %% of the free fall from "
            "%g m (%.1f ms) ignored: too soon to be the mass (sparks?)",
            rec.path,
            n_sparks,
            100 * MIN_FALL_SHARE,
            h,
            1e3 * np.sqrt(2.0 * h / g),
        )
    t_land = float(landing[first])
    t_fall = t_land - run.release_t_s
    ta, tl = det.flights()
    ta_s, tl_s = sample_times(ta, fs, rec.time_s), sample_times(tl, fs, rec.time_s)
    keep = ta_s >= t_land
    ta_s, tl_s, n_joined = mend_splits(ta_s[keep], tl_s[keep])
    if n_joined:
        log.warning(
            "%s: %d bounce flight(s) split by a brief contact joined again: the split "
            "halves broke the geometric sequence of a free drop (sparks?)",
            rec.path,
            n_joined,
        )
    flights = bounce_sequence(t_fall, ta_s, tl_s)
    if flights.size < MIN_BOUNCES:
        raise BouncelabError(
            rec.path,
            f"only {flights.size} bounce(s) of at least {MIN_FLIGHT_S * 1e3:g} ms after the "
            f"first contact; friction and restitution need at least {MIN_BOUNCES} (the fall "
            "and two successive flights: their ratio separates mu from e); a higher drop "
            "gives more",
        )
    if flights.size < CHECKED_BOUNCES:
        log.warning(
            "%s: only %d bounces of at least %g ms after the first contact: mu and e rest on "
            "them and the fall with one degree of freedom to spare, and release_t_s is not "
            "checked against the bounces (%d needed); a higher drop gives more",
            rec.path,
            flights.size,
            MIN_FLIGHT_S * 1e3,
            CHECKED_BOUNCES,
        )
    mu, e, resid = fit_drop(t_fall, flights, h, g)
    data = np.concatenate([[t_fall], flights])
    mu_ci, e_ci = bootstrap_ci(data, h, g, mu, e, resid, n_boot, seed, 1.0 / fs)
    by_bounces = fall_from_bounces(flights, h, g, 1.0 / fs)
    extra = {}
    if by_bounces is not None:
        mu_b, e_b, t_fall_b, sd_b = by_bounces
        extra = {
            "mu_from_bounces": mu_b,
            "restitution_from_bounces": e_b,
            "t_fall_from_bounces_s": t_fall_b,
            "t_fall_from_bounces_sd_s": sd_b,
        }
        # an unphysical friction from the bounces alone says they do not follow the
        # model closely enough to check the release by (the compliant generator's soft
        # contact: mu -0.073, its fall 4.7 ms from the stated one)
        if mu_b >= MU_PLAUSIBLE and abs(t_fall - t_fall_b) > FALL_Z * sd_b:
            log.warning(
                "%s: the fall from release_t_s (%.2f ms) disagrees with the bounces, which "
                "alone give %.2f +- %.2f ms (mu %.3f, e %.3f against the fit's %.3f, %.3f): "
                "check release_t_s",
                rec.path,
                1e3 * t_fall,
                1e3 * t_fall_b,
                1e3 * sd_b,
                mu_b,
                e_b,
                mu,
                e,
            )
    return {
        "mu": mu,
        "mu_ci": [float(mu_ci[0]), float(mu_ci[1])],
        "restitution": e,
        "restitution_ci": [float(e_ci[0]), float(e_ci[1])],
        "n_bounces": int(flights.size),
        "ratio": float(e * np.sqrt((1 - mu) / (1 + mu))),
        "t_fall_s": t_fall,
        "flights_s": [float(v) for v in flights],
        "residuals_s": [float(v) for v in resid],
        "g_m_s2": g,
        "drop_height_m": h,
        "n_boot": int(n_boot),
        "seed": int(seed),
        "run": str(run.run_id),
        **extra,
    }

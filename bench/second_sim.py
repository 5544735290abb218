#!/usr/bin/env python3
"""Second, independent simulator of the cantilever-on-a-carriage rig, and a scorer for `beamtool diagnose`.

Written from a physical description only (no code shared with tools/src/truth or tools/src/model):
a non-uniform Euler-Bernoulli beam (Hermite-cubic FE, consistent mass, 5-point Gauss), reduced to
its lowest clamped modes with per-mode damping, riding a carriage driven by a 1 kHz digital PID loop
with feed-forward (ZOH force), integrated with fixed-step RK4 at 4 kHz (for a linear plant the RK4
step is applied as its exact transition matrix, which is the same arithmetic).

Usage (Python 3.11, numpy, scipy):
    python3 bench/second_sim.py make --out /tmp/second_sim --seed 1 [--cases N] [--only 3,7] [--plan pairs] [--rate 100]
        writes OUT/hidden_gen/caseNN/{rig.toml,sweep.csv,moves.csv,validation.csv} and
        OUT/hidden_gen/key.json ({"effects", "effect", "parameters", "physics"?, "dropped", "tier",
        "imperfect", "true_f_hz", ...} per case). Default plan of 24: 6 nulls, 8 singles,
        3 at the detection limit, 4 pairs, 3 outside the catalogue (case order shuffled by seed).
        --plan pairs: N pairs of the nine catalogue effects (all 36 pairs drawn from), a third imperfect.
    python3 bench/second_sim.py score BEAMTOOL --set /tmp/second_sim [--only case03,case07]
        [--timeout 300] [--jobs 1]
        runs `BEAMTOOL diagnose --rig --fit sweep.csv --fit moves.csv --validate validation.csv
        --json` per case (JSON under SET/score/) and prints per case and a summary. A named
        servo_lag is ignored unless hidden (every rig has a loop); none/unexplained/unknown name
        nothing.
    python3 bench/second_sim.py check      physics sanity numbers (FE vs closed form, ring, momentum)
"""
import argparse, json, math, os, subprocess, sys, time
from concurrent.futures import ThreadPoolExecutor
import numpy as np
from scipy.linalg import eigh

G, TS, NSUB, N_EL, N_MODES = 9.81, 1e-3, 4, 36, 6      # gravity, loop tick, RK4 steps per tick
CATALOGUE = ["base_friction", "servo_lag", "tip_mass", "root_compliance", "quadratic_damping",
             "sensor_delay", "gravity_axial_load", "mount_resonance", "cogging_ripple", "backlash",
             "sensor_gain", "cubic_stiffness"]
OUTSIDE = {"crack": "local bending-stiffness drop over 1-2 cm at 0.2-0.5 L",
           "loose_camera": "camera on a lightly damped support excited by the drive's reaction",
           "sensor_drift": "slow tip-camera offset ramp over each recording",
           "e_drift": "Young's modulus drifting with temperature through each recording"}
PAIRS = [("base_friction", "tip_mass"), ("base_friction", "mount_resonance"),
         ("tip_mass", "sensor_delay"), ("root_compliance", "cogging_ripple"),
         ("quadratic_damping", "backlash")]
LIMIT_POOL = ["base_friction", "tip_mass", "root_compliance", "sensor_delay", "quadratic_damping",
              "cogging_ripple", "backlash", "sensor_gain"]

# ----------------------------------------------------------------------------- beam finite elements
def hermite(xi, h):
    """Hermite cubic shape functions on [0, h] at xi in [0, 1]: N, dN/dx, d2N/dx2 (4 each)."""
    N = np.array([1 - 3*xi**2 + 2*xi**3, h*(xi - 2*xi**2 + xi**3), 3*xi**2 - 2*xi**3, h*(-xi**2 + xi**3)])
    d1 = np.array([-6*xi + 6*xi**2, h*(1 - 4*xi + 3*xi**2), 6*xi - 6*xi**2, h*(-2*xi + 3*xi**2)]) / h
    d2 = np.array([-6 + 12*xi, h*(-4 + 6*xi), 6 - 12*xi, h*(-2 + 6*xi)]) / h**2
    return N, d1, d2

def section(t, x):
    """Width and thickness at x, linear between the stations."""
    xs = [s[0] for s in t["stations"]]
    return np.interp(x, xs, [s[1] for s in t["stations"]]), np.interp(x, xs, [s[2] for s in t["stations"]])

def beam_fe(t, E, rho):
    """Assemble K, M (plus geometric stiffness and point masses) for the beam of truth dict t.

    DOFs per node (w, w'); node 0's w is the root (moves with the root block, removed), node 0's
    w' is removed unless t has a root spring k_root. Returns the free matrices, the rigid-body
    coupling vector c = (M_full r)[free], the beam mass (+ tip mass) and DOF indices."""
    L = t["length"]
    xn = np.linspace(0, L, N_EL + 1)
    if "crack" in t:
        a, ln, _ = t["crack"]
        xn = np.unique(np.round(np.concatenate([xn, [a, a + ln]]), 12))
    n = 2 * len(xn)
    K, M, Kg = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    gp, gw = np.polynomial.legendre.leggauss(5)
    xf = np.linspace(0, L, 4001)                               # mass beyond x for the axial load
    wf, tf = section(t, xf)
    mbeyond = np.concatenate([[0], np.cumsum(0.5*(wf[1:]*tf[1:] + wf[:-1]*tf[:-1])*np.diff(xf))])
    mbeyond = rho * (mbeyond[-1] - mbeyond) + t.get("tip_mass", 0.0)
    sgn = {"hanging": 1.0, "upright": -1.0}.get(t.get("orientation"), 0.0)
    for e in range(len(xn) - 1):
        h = xn[e+1] - xn[e]
        idx = slice(2*e, 2*e + 4)
        for p, wq in zip(gp, gw):
            xi = 0.5*(p + 1); x = xn[e] + xi*h
            N, d1, d2 = hermite(xi, h)
            w, th = section(t, x)
            EI = E * w * th**3 / 12
            if "crack" in t and t["crack"][0] <= x <= t["crack"][0] + t["crack"][1]:
                EI *= 1 - t["crack"][2]
            K[idx, idx] += 0.5*h*wq * EI * np.outer(d2, d2)
            M[idx, idx] += 0.5*h*wq * rho*w*th * np.outer(N, N)
            if sgn:
                Kg[idx, idx] += 0.5*h*wq * sgn*G*np.interp(x, xf, mbeyond) * np.outer(d1, d1)
    K += Kg
    M[n-2, n-2] += t.get("tip_mass", 0.0)
    r = np.zeros(n); r[0::2] = 1.0
    mass = r @ M @ r
    free = list(range(2, n))
    if "k_root" in t:
        free = [1] + free
        K[1, 1] += t["k_root"]
    c = (M @ r)[free]
    Kf, Mf = K[np.ix_(free, free)], M[np.ix_(free, free)]
    return dict(K=Kf, M=Mf, c=c, mass=mass, tip=free.index(n-2),
                root_rot=free.index(1) if "k_root" in t else None)

def modes(fe, k=N_MODES):
    """Lowest k clamped modes: angular frequencies and mass-normalised shapes."""
    lam, phi = eigh(fe["K"], fe["M"], subset_by_index=[0, k-1])
    return np.sqrt(np.maximum(lam, 0.0)), phi

def f1_of(t, E, rho):
    return modes(beam_fe(t, E, rho), 1)[0][0] / (2*np.pi)

# ----------------------------------------------------------------------------- coupled plant
class Plant:
    """Carriage y, optional root block u (mount / backlash), beam modes eta (relative to the root).

    Lagrangian mass matrix in (y, u, eta): positions carriage y, block y+u, beam y+u+Phi eta."""
    def __init__(s, t):
        s.t = t
        fe = beam_fe(t, t["E"], t["rho"])
        s.w, phi = modes(fe)
        s.zeta = np.asarray(t["zeta"][:N_MODES])
        L, mB = phi.T @ fe["c"], fe["mass"]
        s.phi_tip = phi[fe["tip"]]
        s.phi_rot = phi[fe["root_rot"]] if fe["root_rot"] is not None else None
        s.block = "mount" in t or "backlash" in t
        mr = t.get("root_block", 0.0)
        mc = t["base_mass"] - mr
        nm = len(s.w); nb = 2 if s.block else 1; s.nq = nq = nb + nm; s.nb = nb
        Mg = np.zeros((nq, nq)); Kq = np.zeros((nq, nq)); Cq = np.zeros((nq, nq))
        if s.block:
            Mg[:2, :2] = [[mc + mr + mB, mr + mB], [mr + mB, mr + mB]]
            Mg[0, 2:] = Mg[2:, 0] = Mg[1, 2:] = Mg[2:, 1] = L
            if "mount" in t:
                fm, zm = t["mount"]
                Kq[1, 1] = (mr + mB) * (2*np.pi*fm)**2
                Cq[1, 1] = 2*zm*(mr + mB)*2*np.pi*fm
        else:
            Mg[0, 0] = mc + mB; Mg[0, 1:] = Mg[1:, 0] = L
        Mg[nb:, nb:] = np.eye(nm)
        Kq[nb:, nb:] = np.diag(s.w**2); Cq[nb:, nb:] = np.diag(2*s.zeta*s.w)
        s.Mg, s.Minv, s.mB, s.mr, s.L = Mg, np.linalg.inv(Mg), mB, mr, L
        n = nq
        s.A = np.zeros((2*n, 2*n)); s.A[:n, n:] = np.eye(n)
        s.A[n:, :n] = -s.Minv @ Kq; s.A[n:, n:] = -s.Minv @ Cq
        s.b = np.zeros(2*n); s.b[n:] = s.Minv[:, 0]
        s.gen_tip = np.zeros(n); s.gen_tip[0] = 1.0; s.gen_tip[nb:] = s.phi_tip   # tip force -> gen. forces
        if s.block: s.gen_tip[1] = 1.0
        s.nonlinear = any(k in t for k in ("friction", "cogging", "drag", "backlash", "k3", "e_drift"))
        if "backlash" in t:
            s.k_contact = (mr + mB) * (2*np.pi*80.0)**2
            s.c_contact = 2*0.3*math.sqrt(s.k_contact*(mr + mB))

    def tip_abs(s, X):
        """Absolute tip position (lab frame) for states X (..., 2n)."""
        return X[..., 0] + (X[..., 1] if s.block else 0.0) + X[..., s.nb:s.nq] @ s.phi_tip

    def momentum(s, X):
        return X[..., s.nq:] @ s.Mg[0]

    def h(s, x, tnow):
        """Nonlinear generalized forces (friction, cogging, drag, play, cubic clamp, E drift)."""
        t, n, nb = s.t, s.nq, s.nb
        f = np.zeros(n)
        v = x[n]
        if "friction" in t:
            fc, cv = t["friction"]
            f[0] -= fc*math.tanh(v/1e-3) + cv*v
        if "cogging" in t:
            a, p = t["cogging"]
            f[0] += a*math.sin(2*math.pi*x[0]/p)
        if "drag" in t:
            vt = v + (x[n+1] if s.block else 0.0) + float(x[n+nb:] @ s.phi_tip)
            f -= t["drag"]*abs(vt)*vt * s.gen_tip
        if "backlash" in t:
            u, du, hb = x[1], x[n+1], 0.5*t["backlash"]
            pen = u - hb if u > hb else (u + hb if u < -hb else 0.0)
            fs = s.k_contact*pen + (s.c_contact*du if pen else 0.0)
            fs = max(fs, 0.0) if pen > 0 else (min(fs, 0.0) if pen < 0 else 0.0)   # compressive only
            fg = t["guide_friction"]*math.tanh((v + du)/5e-3)       # block on a rail fixed to the lab
            f[1] -= fs + fg; f[0] -= fg
        if "k3" in t:
            th = float(x[nb:n] @ s.phi_rot)
            f[nb:] -= t["k3"]*th**3 * s.phi_rot
        if "e_drift" in t:
            d, T = t["e_drift"]
            f[nb:] -= d*min(tnow/T, 1.0) * s.w**2 * x[nb:n]
        return s.Minv @ f

# ----------------------------------------------------------------------------- loop and integration
def simulate(p, ref, loop, sub=NSUB):
    """Run the 1 kHz PID (+FF) loop on the plant for command ref (1 kHz grid). Returns states X at
    every tick and the force applied during the tick that starts there."""
    n2 = 2*p.nq; dt = TS/sub
    vel = np.gradient(ref, TS); acc = np.gradient(vel, TS)
    m, bw = loop["m_nom"], loop["bw_hz"]
    w = 2*np.pi*bw
    Kp, Kd, Ki = m*w*w, 1.4*m*w, m*w**3/8
    a_d = TS/(1/(2*np.pi*min(5*bw, 250.0)) + TS)
    ff = loop["m_est"]*loop["ka"]*acc + loop["c_est"]*loop["kv"]*vel
    N = len(ref)
    X = np.zeros((N, n2)); F = np.zeros(N)
    x = np.zeros(n2); integ = 0.0; eprev = 0.0; df = 0.0
    A, b = p.A, p.b
    if not p.nonlinear:                       # RK4 transition matrices of the linear system
        Ah = A*dt; I = np.eye(n2)
        P = I + Ah + Ah@Ah/2 + Ah@Ah@Ah/6 + Ah@Ah@Ah@Ah/24
        Q = (I*dt + Ah*dt/2 + Ah@Ah*dt/6 + Ah@Ah@Ah*dt/24) @ b
        Pt = np.linalg.matrix_power(P, sub)
        Qt = sum(np.linalg.matrix_power(P, k) for k in range(sub)) @ Q
    for k in range(N):
        X[k] = x
        e = ref[k] - round(x[0]*1e7)*1e-7          # loop reads the encoder at 0.1 um (logged at 1 um)
        df += a_d*((e - eprev)/TS - df); eprev = e
        Fk = ff[k] + Kp*e + Ki*integ + Kd*df
        integ += e*TS
        F[k] = Fk
        if not p.nonlinear:
            x = Pt @ x + Qt*Fk
            continue
        t0 = k*TS
        for j in range(sub):
            tt = t0 + j*dt
            k1 = A@x + b*Fk + np.concatenate([np.zeros(p.nq), p.h(x, tt)])
            x2 = x + 0.5*dt*k1
            k2 = A@x2 + b*Fk + np.concatenate([np.zeros(p.nq), p.h(x2, tt + dt/2)])
            x3 = x + 0.5*dt*k2
            k3 = A@x3 + b*Fk + np.concatenate([np.zeros(p.nq), p.h(x3, tt + dt/2)])
            x4 = x + dt*k3
            k4 = A@x4 + b*Fk + np.concatenate([np.zeros(p.nq), p.h(x4, tt + dt)])
            x = x + dt/6*(k1 + 2*k2 + 2*k3 + k4)
        if not np.all(np.isfinite(x)) or abs(x[0]) > 1.0:
            raise RuntimeError("plant diverged")
    return X, F

# ----------------------------------------------------------------------------- commands
def ptp(tt, t0, dur, d):
    """Minimum-jerk move of d metres starting at t0 lasting dur, evaluated at times tt."""
    s = np.clip((tt - t0)/dur, 0, 1)
    return d*(10*s**3 - 15*s**4 + 6*s**5)

def moves_cmd(plan, f1, z, T):
    """Command (1 kHz, T s) for a list plan of (t_start, dur, delta, shaped), ZV shaper at f1 (nominal)."""
    tt = np.arange(0, T, TS); c = np.zeros_like(tt)
    Kz = math.exp(-z*math.pi/math.sqrt(1 - z*z)); td = 0.5/(f1*math.sqrt(1 - z*z))
    for t0, dur, d, sh in plan:
        if sh:
            c += ptp(tt, t0, dur, d/(1 + Kz)) + ptp(tt, t0 + td, dur, d*Kz/(1 + Kz))
        else:
            c += ptp(tt, t0, dur, d)
    return c

def sweep_cmd(T, f0, f1, amp, t_lead=0.5, fade=3.0, t_tail=1.0):
    tt = np.arange(0, t_lead + T + t_tail, TS); s = np.clip(tt - t_lead, 0, T)
    k = math.log(f1/f0)/T
    ph = 2*np.pi*f0*(np.exp(k*s) - 1)/k
    win = np.clip(np.minimum(s, T - s)/fade, 0, 1); win = 0.5 - 0.5*np.cos(np.pi*win)
    return amp*win*np.sin(ph)

def make_commands(rng, f1, z):
    """sweep (~90 s), moves (~47 s), validation (~52 s) commands on the 1 kHz grid."""
    sweep = sweep_cmd(rng.uniform(88, 90), 0.2, 10.0, rng.uniform(0.8e-3, 1.2e-3))
    plan, t, pos = [], 0.5, 0.0
    while t < 44:
        tgt = rng.uniform(0, 0.05)
        while abs(tgt - pos) < 0.01: tgt = rng.uniform(0, 0.05)
        dur = rng.uniform(0.25, 0.4); sh = rng.random() < 0.4
        plan.append((t, dur, tgt - pos, sh)); pos = tgt
        t += dur + (0.5/f1 if sh else 0) + rng.uniform(5, 8)
    moves = moves_cmd(plan, f1, z, t - rng.uniform(2, 4))
    plan, t, pos = [], 0.5, 0.0
    for _ in range(2):
        tgt = rng.uniform(0.01, 0.04); dur = rng.uniform(0.18, 0.35)
        plan.append((t, dur, tgt - pos, rng.random() < 0.4)); pos = tgt; t += dur + rng.uniform(7, 9)
    d = -pos/4 if pos > 0.02 else rng.uniform(0.004, 0.008)
    for _ in range(4):                                         # staircase of short moves
        plan.append((t, 0.15, d, False)); pos += d; t += 0.3
    t += 5
    plan.append((t, 0.3, -pos, False)); t += 0.3 + 5; pos = 0.0
    plan.append((t, 0.3, 0.02, rng.random() < 0.5)); t += 0.3 + 15          # 15 s rest
    v = moves_cmd(plan, f1, z, t)
    v = np.concatenate([v, 0.02 + sweep_cmd(6.0, 0.5, 6.0, 3e-4, 0.0, 1.5, 1.0)])
    return {"sweep": sweep, "moves": moves, "validation": v}

# ----------------------------------------------------------------------------- case drawing
def draw_rig(rng):
    """Geometry, materials, believed and true values; redraw until nominal f1 is 0.8-3 Hz."""
    while True:
        steel = rng.random() < 0.6
        E_cat, rho_cat = (rng.choice([1.9e11, 2.0e11, 2.1e11]), rng.choice([7850.0, 7900.0, 8000.0])) \
            if steel else (rng.choice([6.9e10, 7.0e10]), rng.choice([2700.0, 2710.0]))
        L = rng.uniform(0.5, 1.1); w0 = rng.uniform(0.02, 0.035); th0 = rng.uniform(0.8e-3, 2e-3)
        kind = rng.choice(["uniform", "width", "thickness", "both", "three"])
        w1 = w0*rng.uniform(0.6, 0.9) if kind in ("width", "both", "three") else w0
        th1 = th0*rng.uniform(0.7, 0.95) if kind in ("thickness", "both") else th0
        st = [(0.0, w0, th0), (L, w1, th1)]
        if kind == "three":
            st.insert(1, (L*rng.uniform(0.3, 0.7), w0*rng.uniform(0.85, 1.0), th0))
        t = dict(length=L, stations=st)
        f1 = f1_of(t, E_cat, rho_cat)
        if 0.8 <= f1 <= 3.0:
            break
    base = rng.uniform(1.5, 4.0)
    rig = dict(t, E=float(E_cat), rho=float(rho_cat), base_mass=base)
    truth = dict(t, E=E_cat*(1 + rng.uniform(-0.05, 0.05)), rho=rho_cat*(1 + rng.uniform(-0.02, 0.02)),
                 base_mass=base*(1 + rng.uniform(-0.05, 0.05)),
                 zeta=list(np.exp(rng.uniform(np.log(0.003), np.log(0.03), N_MODES))))
    return rig, truth, f1

def k_root_for_drop(t, drop):
    """Rotational root stiffness that lowers f1 by the fraction drop (bisection in log k).

    Searched over k L/EI = 1 … 1e6: a stiffer spring changes f1 by less than any drop asked for, and
    beyond about 1e12 the FE stiffness matrix loses the beam to rounding (f1 came out 0 and the
    bisection ran to k = 1e17 N·m/rad: seed 4 case15, seed 6 case17)."""
    f0 = f1_of(t, t["E"], t["rho"])
    lo, hi = 0.0, 6.0
    EIL = t["E"]*t["stations"][0][1]*t["stations"][0][2]**3/12/t["length"]
    for _ in range(40):
        mid = 0.5*(lo + hi)
        f = f1_of(dict(t, k_root=EIL*10**mid), t["E"], t["rho"])
        lo, hi = (mid, hi) if f < f0*(1 - drop) else (lo, mid)
    return EIL*10**(0.5*(lo + hi))

def apply_effect(rng, name, t, limit, beam_mass):
    """Set the truth fields of one effect on t; return the key parameters (SI)."""
    s = 0.5 if limit else 1.0
    if name == "base_friction":
        fc = rng.uniform(0.3, 2.0)*s; cv = rng.uniform(0.5, 3.0)*s if rng.random() < 0.4 else 0.0
        t["friction"] = (fc, cv)
        return {"friction_n": fc, **({"viscous_n_s_per_m": cv} if cv else {})}
    if name == "servo_lag":
        t["servo_bw"] = rng.uniform(15, 25) if limit else rng.uniform(5, 15)
        return {"servo_bandwidth_hz": t["servo_bw"]}
    if name == "tip_mass":
        t["tip_mass"] = beam_mass*rng.uniform(0.02, 0.15)*s
        return {"tip_mass_kg": t["tip_mass"]}
    if name == "root_compliance":
        t["k_root"] = k_root_for_drop(t, rng.uniform(0.02, 0.08)*s)
        return {"root_stiffness_nm_per_rad": t["k_root"]}
    if name == "quadratic_damping":
        t["drag"] = rng.uniform(0.005, 0.03)*s
        return {"tip_drag_coefficient_kg_per_m": t["drag"]}
    if name == "sensor_delay":
        t["delay"] = rng.uniform(0.005, 0.03)*s
        return {"sensor_delay_s": t["delay"]}
    if name == "gravity_axial_load":
        o = rng.choice(["hanging", "upright"])
        if o == "upright" and f1_of(dict(t, orientation=o), t["E"], t["rho"]) < 0.7*f1_of(t, t["E"], t["rho"]):
            o = "hanging"                                      # too close to buckling
        t["orientation"] = str(o)
        return {"orientation": str(o)}
    if name == "mount_resonance":
        fm, zm = rng.uniform(10, 30), rng.uniform(0.02, 0.08)
        t["mount"] = (fm, zm); t["root_block"] = rng.uniform(0.2, 0.5)
        return {"mount_frequency_hz": fm, "mount_damping_ratio": zm, "root_block_kg": t["root_block"]}
    if name == "cogging_ripple":
        t["cogging"] = (rng.uniform(0.3, 1.0)*s, rng.uniform(0.01, 0.04))
        return {"cogging_amplitude_n": t["cogging"][0], "cogging_pitch_m": t["cogging"][1]}
    if name == "backlash":
        t["backlash"] = rng.uniform(0.05e-3, 0.3e-3)*s; t["root_block"] = rng.uniform(0.2, 0.5)
        return {"backlash_m": t["backlash"]}
    if name == "sensor_gain":
        g = rng.uniform(0.02, 0.05)*s*rng.choice([-1, 1])
        t["gain"] = 1 + g
        return {"sensor_gain": t["gain"]}
    if name == "cubic_stiffness":
        t["k_root"] = k_root_for_drop(t, rng.uniform(0.01, 0.04))
        fe = beam_fe(t, t["E"], t["rho"])                      # root rotation at 20 mm static tip
        f = np.zeros(len(fe["K"])); f[fe["tip"]] = 1.0
        q = np.linalg.solve(fe["K"], f); th_ref = q[fe["root_rot"]]*0.02/q[fe["tip"]]
        t["k3"] = rng.uniform(0.3, 1.0)*t["k_root"]/th_ref**2
        return {"root_stiffness_nm_per_rad": t["k_root"], "cubic_root_stiffness_nm_per_rad3": t["k3"]}
    raise ValueError(name)

def apply_outside(rng, kind, t):
    L = t["length"]
    if kind == "crack":
        t["crack"] = (L*rng.uniform(0.2, 0.5), rng.uniform(0.01, 0.02), rng.uniform(0.3, 0.6))
        return {"crack_x_m": t["crack"][0], "crack_length_m": t["crack"][1], "ei_drop": t["crack"][2]}
    if kind == "loose_camera":
        t["camera"] = (rng.uniform(5, 12), rng.uniform(0.02, 0.05), rng.uniform(60, 150))
        return {"camera_mount_hz": t["camera"][0], "camera_zeta": t["camera"][1], "frame_mass_kg": t["camera"][2]}
    if kind == "sensor_drift":
        t["drift"] = rng.uniform(1e-4, 5e-4)*rng.choice([-1, 1])
        return {"drift_m_per_recording": t["drift"]}
    if kind == "e_drift":
        t["e_drift"] = (rng.uniform(0.02, 0.04)*rng.choice([-1, 1]), 0.0)
        return {"e_change_per_recording": t["e_drift"][0]}
    raise ValueError(kind)

def default_plan(rng, n):
    """List of (tier, [effects] or outside kind, imperfections) of length n (24 by default)."""
    singles = list(rng.permutation(CATALOGUE)[:8]); limits = list(rng.permutation(LIMIT_POOL)[:3])
    pairs = [PAIRS[i] for i in rng.permutation(len(PAIRS))[:4]]; outs = list(rng.permutation(list(OUTSIDE))[:3])
    nulls = [("null", [], imp) for imp in (["rate100"], ["rate50", "drop_force"], ["rate200"],
             ["rate500", "drop_both"], ["noise3"], ["dropped_frames", "drop_base"])]
    plan = nulls + [("single", [e], []) for e in singles] + [("limit", [e], []) for e in limits] \
        + [("pair", list(p), []) for p in pairs] + [("outside", [k], []) for k in outs]
    for i in rng.choice(np.arange(6, len(plan)), 4, replace=False):       # a few imperfect recordings
        plan[i] = (plan[i][0], plan[i][1], [str(rng.choice(["drop_force", "drop_both", "dropped_frames", "noise3"]))])
    plan = [plan[i] for i in rng.permutation(len(plan))]
    return [plan[i % len(plan)] for i in range(n)]

# ----------------------------------------------------------------------------- recording
def record(rng, p, t, X, F, fs, noise, name):
    """Sample the 1 kHz trace at fs with the sensors' quantisation, noise and effects."""
    T = np.arange(len(F))*TS
    y = X[:, 0]; tip = p.tip_abs(X)
    if "gain" in t: tip = y + t["gain"]*(tip - y)
    if "delay" in t: tip = np.interp(T - t["delay"], T, tip, left=0.0)
    if "camera" in t:                                          # camera frame excited by the reaction -F
        from scipy.signal import lsim
        fc, zc, mf = t["camera"]; wc = 2*np.pi*fc
        cam = lsim(([1.0/mf], [1.0, 2*zc*wc, wc*wc]), -F, T)[1]
        tip = tip - cam
    if "drift" in t: tip = tip + t["drift"]*T/T[-1]
    step = int(round(1.0/(fs*TS)))
    sel = np.arange(0, len(F), step)
    cols = {"time_s": T[sel], "base_cmd_m": t["_ref"][name][sel],
            "base_pos_m": np.round(y[sel]*1e6)*1e-6,
            "tip_pos_m": np.round((tip[sel] + rng.normal(0, noise["cam"], len(sel)))*1e5)*1e-5,
            "force_n": F[sel] + rng.normal(0, noise["force"], len(sel))}
    return cols

def write_csv(path, cols, dropped, frames_drop, rng):
    names = [c for c in ["time_s", "base_cmd_m", "base_pos_m", "tip_pos_m", "force_n"] if c not in dropped]
    keep = np.ones(len(cols["time_s"]), bool)
    if frames_drop:
        keep[2:] = rng.random(len(keep) - 2) >= 0.01
    fmt = {"time_s": "%.4f", "force_n": "%.4f"}
    data = np.column_stack([cols[c][keep] for c in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="",
               fmt=[fmt.get(c, "%.7f") for c in names])

def write_rig(path, rig, fs):
    st = "\n".join(f"  {{ x_m = {x:.10g}, width_m = {w:.10g}, thickness_m = {h:.10g} }}," for x, w, h in rig["stations"])
    with open(path, "w") as f:
        f.write(f"[beam]\nlength_m = {rig['length']:.10g}\ndensity_kg_m3 = {rig['rho']:.1f}\n"
                f"youngs_modulus_pa = {rig['E']:.4g}\nstations = [\n{st}\n]\n\n[base]\nmass_kg = {rig['base_mass']:.10g}\n\n"
                f"[damping]\nratios = [0.0074, 0.0074]\n\n[sensors]\nsample_rate_hz = {float(fs)}\n")

def make_case(seed, idx, spec, outdir):
    """Draw, simulate and write one case; return its key entry."""
    rng = np.random.default_rng([seed, idx])
    tier, what, imp = spec
    rig, t, f1_nom = draw_rig(rng)
    beam_mass = beam_fe(t, t["E"], t["rho"])["mass"]
    params, physics = {}, None
    if tier == "outside":
        params = apply_outside(rng, what[0], t); physics = f"{what[0]}: {OUTSIDE[what[0]]}"
        effects = []
    else:
        effects = list(what)
        for e in effects:
            params.update(apply_effect(rng, e, t, tier == "limit", beam_mass))
    rates = [r[4:] for r in imp if r.startswith("rate")]
    fs = int(rates[0]) if rates else int(rng.choice([50, 100, 200, 500], p=[0.1, 0.6, 0.15, 0.15]))
    dropped = {"drop_force": ["force_n"], "drop_base": ["base_pos_m"], "drop_both": ["base_pos_m", "force_n"]}
    dropped = sorted({c for r in imp for c in dropped.get(r, [])})
    k3 = 3.0 if "noise3" in imp else 1.0
    noise = {"cam": k3*rng.uniform(10e-6, 40e-6), "force": k3*rng.uniform(0.02, 0.05)}
    m_nom = rig["base_mass"] + beam_mass*rig["rho"]/t["rho"]
    loop = dict(m_nom=m_nom, m_est=m_nom*(1 + rng.uniform(0.02, 0.05)*rng.choice([-1, 1])),
                bw_hz=t.get("servo_bw", rng.uniform(30, 50)), ka=rng.uniform(0.9, 1.0),
                kv=rng.uniform(0.9, 1.0), c_est=rng.uniform(0.0, 2.0))
    cmds = make_commands(rng, f1_nom, 0.0074)
    t["_ref"] = cmds
    if "backlash" in t:                       # rail friction holds the block in the gap: 1.5x peak inertia
        a_pk = max(np.abs(np.gradient(np.gradient(c, TS), TS)).max() for c in cmds.values())
        t["guide_friction"] = 1.5*(t["root_block"] + beam_mass)*a_pk
        dropped = sorted(set(dropped) | {"force_n"})           # the rail friction would show in the force
    d = os.path.join(outdir, f"case{idx:02d}"); os.makedirs(d, exist_ok=True)
    p = Plant(t)
    for name, ref in cmds.items():
        if "e_drift" in t: t["e_drift"] = (t["e_drift"][0], len(ref)*TS)
        X, F = simulate(p, ref, loop)
        cols = record(rng, p, t, X, F, fs, noise, name)
        write_csv(os.path.join(d, f"{name}.csv"), cols, dropped, "dropped_frames" in imp, rng)
    write_rig(os.path.join(d, "rig.toml"), rig, fs)
    key = {"effects": effects, "effect": effects[0] if effects else "none", "parameters": params,
           "dropped": dropped, "tier": tier, "imperfect": [i for i in imp if not i.startswith("rate")],
           "sample_rate_hz": fs, "true_f_hz": [float(w/(2*np.pi)) for w in p.w[:2]],
           "nominal_f1_hz": f1_nom, "loop": {k: float(v) for k, v in loop.items()}}
    if physics: key["physics"] = physics
    return key

NINE = CATALOGUE[:9]                                           # the independent set's catalogue

def pairs_plan(rng, n):
    """n pairs drawn without repetition from all 36 pairs of the nine catalogue effects, a third of
    them with a channel dropped or another imperfection (the hidden set's "pairs of effects")."""
    combos = [(a, b) for i, a in enumerate(NINE) for b in NINE[i + 1:]]
    imps = [[], [], ["drop_both"], ["drop_force"], ["dropped_frames"], ["noise3"]]
    return [("pair", list(combos[i]), list(imps[rng.integers(len(imps))]))
            for i in rng.permutation(len(combos))[:n]]

def cmd_make(a):
    out = os.path.join(a.out, "hidden_gen"); os.makedirs(out, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    plan = pairs_plan(rng, a.cases) if a.plan == "pairs" else default_plan(rng, a.cases)
    if a.rate:                                                 # one sample rate for every case
        plan = [(t, w, [i for i in imp if not i.startswith("rate")] + [f"rate{a.rate}"]) for t, w, imp in plan]
    kp = os.path.join(out, "key.json")
    key = json.load(open(kp)) if a.only and os.path.exists(kp) else {}
    only = {int(x) for x in a.only.split(",")} if a.only else None
    for i, spec in enumerate(plan):
        if only and i not in only: continue
        t0 = time.time()
        key[f"case{i:02d}"] = make_case(a.seed, i, spec, out)
        k = key[f"case{i:02d}"]
        print(f"case{i:02d} {k['tier']:8s} {'+'.join(k['effects']) or k.get('physics', 'none')[:30]:32s} "
              f"{k['sample_rate_hz']:4d} Hz f1 {k['true_f_hz'][0]:.3f} drop {k['dropped']} {time.time()-t0:.1f}s", flush=True)
        json.dump(dict(sorted(key.items())), open(kp, "w"), indent=1)

# ----------------------------------------------------------------------------- scorer
NOTHING = {"none", "unexplained", "unknown"}

def run_one(tool, d, case, timeout, outdir):
    js = os.path.join(outdir, f"{case}.json")
    if os.path.exists(js): os.remove(js)
    c = os.path.join(d, case); t0 = time.time()
    try:
        r = subprocess.run([tool, "diagnose", "--rig", f"{c}/rig.toml", "--fit", f"{c}/sweep.csv",
                            "--fit", f"{c}/moves.csv", "--validate", f"{c}/validation.csv", "--json", js],
                           capture_output=True, text=True, timeout=timeout)
        ok = r.returncode == 0 and os.path.exists(js)
        err = None if ok else (r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1][:80]
    except subprocess.TimeoutExpired:
        ok, err = False, "timeout"
    sec = time.time() - t0
    if not ok: return None, False, sec, err
    j = json.load(open(js))
    named = set()
    for e in j.get("effects") or []:
        nm = e.get("effect") if isinstance(e, dict) else str(e)
        if nm and nm not in NOTHING: named.add(nm)
    return named, bool(j.get("unexplained")), sec, None

def cmd_score(a):
    d = os.path.join(a.set, "hidden_gen"); key = json.load(open(os.path.join(d, "key.json")))
    cases = sorted(key) if not a.only else [c.strip() for c in a.only.split(",")]
    outdir = os.path.join(a.set, "score"); os.makedirs(outdir, exist_ok=True)
    with ThreadPoolExecutor(a.jobs) as ex:
        res = dict(zip(cases, ex.map(lambda c: run_one(a.beamtool, d, c, a.timeout, outdir), cases)))
    tally = {k: [0, 0] for k in ("null", "single", "limit", "outside", "unexpl")}
    tp = fn = fp = 0
    for c in cases:
        k = key[c]; hid = set(k["effects"]); named, unex, sec, err = res[c]
        if named is not None and "servo_lag" not in hid: named.discard("servo_lag")
        ok = named is not None and named == hid
        tier = k["tier"]
        if tier == "pair":
            nm = named or set(); tp += len(nm & hid); fn += len(hid - nm); fp += len(nm - hid)
        elif tier in tally:
            tally[tier][0] += ok; tally[tier][1] += 1
        if tier == "outside":
            tally["unexpl"][0] += bool(ok and unex); tally["unexpl"][1] += 1
        hidden = "+".join(sorted(hid)) or ("none (" + k["physics"].split(":")[0] + ")" if "physics" in k else "none")
        shown = "ERROR " + str(err) if named is None else ("+".join(sorted(named)) or "none")
        extra = f"  unexplained {'yes' if unex else 'no'}" if tier == "outside" else ""
        print(f"{c} {tier:7s} key {hidden:36s} named {shown:36s} {'OK' if ok else 'WRONG':5s} {sec:6.1f}s{extra}", flush=True)
    n = tally["null"]
    print(f"\nnulls: false alarms {n[1]-n[0]}/{n[1]}")
    print(f"singles right {tally['single'][0]}/{tally['single'][1]}; limit right {tally['limit'][0]}/{tally['limit'][1]}")
    print(f"pairs recall {tp}/{tp+fn}, precision {tp}/{tp+fp}")
    print(f"outside -> no catalogue name {tally['outside'][0]}/{tally['outside'][1]}; "
          f"`unexplained` located {tally['unexpl'][0]}/{tally['unexpl'][1]}")

# ----------------------------------------------------------------------------- sanity checks
def cmd_check(a):
    """FE vs closed form, ring after a move, momentum balance, following error."""
    rng = np.random.default_rng(5)
    for L, w, th, E, rho in [(0.9, 0.025, 1e-3, 2.0e11, 7850.0), (0.6, 0.03, 1.5e-3, 6.9e10, 2700.0)]:
        t = dict(length=L, stations=[(0, w, th), (L, w, th)])
        om, _ = modes(beam_fe(t, E, rho), 3)
        EI, rA = E*w*th**3/12, rho*w*th
        cf = [b*b/(2*np.pi*L*L)*math.sqrt(EI/rA) for b in (1.8751041, 4.6940911, 7.8547574)]
        print("uniform L=%.2f: FE %s closed %s rel.err %s" % (L, np.round(om/2/np.pi, 5), np.round(cf, 5),
              ["%.1e" % (o/2/np.pi/c - 1) for o, c in zip(om, cf)]))
    rig, t, f1 = draw_rig(rng)
    p = Plant(t)
    loop = dict(m_nom=rig["base_mass"] + p.mB, m_est=(rig["base_mass"] + p.mB)*1.03, bw_hz=40, ka=0.95, kv=0.95, c_est=0.0)
    ref = ptp(np.arange(0, 12, TS), 0.5, 0.3, 0.03)
    X, F = simulate(p, ref, loop)
    T = np.arange(len(F))*TS; w = p.tip_abs(X) - X[:, 0]
    m = T > 2; zc = T[m][1:][np.diff(np.sign(w[m])) != 0]
    pk = [np.abs(w[(T > a) & (T < a + 1/f1)]).max() for a in (2, 6)]
    print(f"ring: f1 modal {p.w[0]/2/np.pi:.4f} Hz, from zero crossings {1/(2*np.mean(np.diff(zc))):.4f} Hz, "
          f"peak |w| at 2 s {pk[0]*1e3:.2f} mm, at 6 s {pk[1]*1e3:.2f} mm (zeta1 {p.zeta[0]:.4f}: "
          f"expected ratio {math.exp(-p.zeta[0]*p.w[0]*4):.3f}, got {pk[1]/pk[0]:.3f})")
    dP = np.diff(p.momentum(X))/TS                              # over each ZOH tick
    print(f"momentum: rms(F) {np.sqrt(np.mean(F**2)):.3f} N, rms(F - dP/dt) {np.sqrt(np.mean((F[:-1] - dP)**2)):.2e} N")
    e = ref - X[:, 0]
    print(f"following error (40 Hz loop, FF 0.95, mass +3 %): peak {np.abs(e).max()*1e6:.1f} um, "
          f"rms in move {np.sqrt(np.mean(e[(T > .5) & (T < .8)]**2))*1e6:.1f} um")
    t0 = time.time(); simulate(p, sweep_cmd(86, 0.2, 10, 1e-3), loop)
    print(f"sweep 90 s linear plant: {time.time()-t0:.1f} s")
    t["friction"] = (1.0, 0.0); p2 = Plant(t); t0 = time.time(); simulate(p2, ref[:10000], loop)
    print(f"10 s nonlinear (RK4 with friction): {time.time()-t0:.1f} s")

def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sp = ap.add_subparsers(dest="cmd", required=True)
    m = sp.add_parser("make"); m.add_argument("--out", default="/tmp/second_sim"); m.add_argument("--seed", type=int, default=1)
    m.add_argument("--cases", type=int, default=24); m.add_argument("--only", default=None, help="case indices, e.g. 3,7")
    m.add_argument("--plan", choices=["default", "pairs"], default="default",
                   help="pairs: every case a pair of the nine catalogue effects of the independent set")
    m.add_argument("--rate", type=int, default=None, help="sample rate (Hz) of every case, e.g. 100 as the independent set")
    s = sp.add_parser("score"); s.add_argument("beamtool"); s.add_argument("--set", default="/tmp/second_sim")
    s.add_argument("--only"); s.add_argument("--timeout", type=float, default=300); s.add_argument("--jobs", type=int, default=1)
    sp.add_parser("check")
    a = ap.parse_args()
    {"make": cmd_make, "score": cmd_score, "check": cmd_check}[a.cmd](a)

if __name__ == "__main__":
    main()

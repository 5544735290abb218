//! Block 1 of the chain, the servo: the base follows its command through a finite-bandwidth
//! position loop whose command → base transfer function has order 1–4 ([`ServoLaw`]): order 2 is
//! `ÿ + 2ζ_sω_s ẏ + ω_s² y = k_a r̈ + 2ζ_sω_s k_v ṙ + ω_s² r`, i.e. the following error
//! e = y − r obeys `ë + 2ζ_sω_s ė + ω_s² e = −(1 − k_a) r̈ − 2ζ_sω_s (1 − k_v) ṙ` (`servo_lag`;
//! k_v = k_a = 0 is a plain 2nd-order lag, PID with velocity/acceleration feed-forward has
//! fractions near 1); order 3 adds the integral action of a PID loop, order 4 a lag of the
//! drive force, order 1 is a first-order lag; orders 2–4 are simulated with the beam's
//! reaction on the carriage (eq. 5 in modal form, [`coupled_servo`]) and with the carriage
//! forces of [`super::carriage`], which the loop must overcome ([`CarriageLoad`]); predicted
//! `base_pos_m`.

use super::beam::{root_generator, BeamCache};
use super::carriage::CarriageLoad;
use super::discrete::{advance, at_rest, bounded_expm, second_order};
use super::params::Params;

/// Carriage position under a position loop that carries the beam: the loop force
/// `F = M [k_a r̈ + 2ζω (k_v ṙ − ẏ) + ω² (r − y)]` (M the total moving mass the drive is tuned
/// for) acts on the carriage, which the beam modes push back (eq. 5 in modal form):
/// `(M − ΣΓ²) ÿ = F + Σ Γ_r (2ζ_rω_r η̇_r + ω_r² η_r)`, `η̈_r + 2ζ_rω_r η̇_r + ω_r² η_r = −Γ_r ÿ`.
/// For a rigid load this is the uncoupled loop of [`second_order`]. Exact for a piecewise-linear
/// command (r̈ as kicks at the samples): one matrix exponential per parameter set. A carriage
/// `load` (friction, cogging) acts on the carriage as `− F_load(y, ẏ)` ([`LoadedLoop`]).
pub(crate) fn coupled_servo(
    r: &[f64],
    dt: f64,
    omega: f64,
    zeta: f64,
    ff: (f64, f64),
    c: &BeamCache,
    load: Option<&CarriageLoad>,
) -> Vec<f64> {
    let n = r.len();
    let nm = c.omega.len();
    let m_tot = c.total_mass;
    let sum_g2: f64 = c.gamma.iter().map(|g| g * g).sum();
    let m_eff = (m_tot - sum_g2).max(1e-9 * m_tot);
    let (kv, ka) = ff;
    // z = [y, ẏ, (η_j, η̇_j)…, F_load?, r, ṙ]; within a sample interval r is linear (ṙ
    // constant), so the interval map is exactly exp(A dt)
    let dim = 4 + 2 * nm + usize::from(load.is_some());
    let (ri, vi) = (dim - 2, dim - 1);
    let li = load.map(|_| 2 + 2 * nm);
    let mut acc_row = vec![0.0; dim];
    acc_row[0] = -m_tot * omega * omega / m_eff;
    acc_row[1] = -m_tot * 2.0 * zeta * omega / m_eff;
    acc_row[ri] = m_tot * omega * omega / m_eff;
    acc_row[vi] = m_tot * 2.0 * zeta * omega * kv / m_eff;
    if let Some(li) = li {
        acc_row[li] = -1.0 / m_eff;
    }
    let generator = |damper: f64| {
        let mut row = acc_row.clone();
        row[1] -= damper / m_eff;
        root_generator(&mut row, m_eff, Some(c))
    };
    let Some(phi) = bounded_expm(generator(0.0), dt, 1e4) else {
        return vec![f64::NAN; n];
    };
    let loaded = match load.zip(li) {
        Some((l, li)) => match LoadedLoop::new(l, li, m_eff, dt, &generator, 1e4) {
            Some(ll) => Some(ll),
            None => return vec![f64::NAN; n],
        },
        None => None,
    };
    let mut saved = vec![0.0; dim];
    let (mut zv, mut tmp) = (vec![0.0; dim], vec![0.0; dim]);
    zv[0] = r[0];
    let mut y = Vec::with_capacity(n);
    let mut v_prev = 0.0;
    for k in 0..n {
        y.push(zv[0]);
        let v = if k + 1 < n {
            (r[k + 1] - r[k]) / dt
        } else {
            0.0
        };
        // acceleration feed-forward of the velocity step at this sample: an impulse
        let kick = ka * m_tot * (v - v_prev) / m_eff;
        zv[1] += kick;
        for j in 0..nm {
            zv[3 + 2 * j] -= c.gamma[j] * kick;
        }
        v_prev = v;
        zv[ri] = r[k];
        zv[vi] = v;
        match &loaded {
            Some(ll) => ll.advance(&phi, &mut zv, &mut tmp, &mut saved),
            None => advance(&phi, &mut zv, &mut tmp),
        }
        if !zv[0].is_finite() {
            y.extend(std::iter::repeat(f64::NAN).take(n - y.len()));
            break;
        }
    }
    y
}

/// A loop whose carriage carries a [`CarriageLoad`] (state index `li` holds the load's force,
/// constant over a step), stepped one sample interval at a time by a linearly implicit map
/// (a Rosenbrock step; Hairer & Wanner, *Solving ODEs II*, IV.7): the load is stiff only
/// inside the friction's smoothing band (|v| ≲ v_s), where the smoothed Coulomb force is a
/// damper of slope s(v) = F_c sech²(v/v_s) / v_s + c_v that a held force over a whole interval
/// would overshoot (s dt / m ≫ 1 at 100 Hz: a chatter of F_c dt / m).
/// - The interval map with a damper c_k in the generator — one of a ladder c_k = s(0) 2^−k,
///   k = 0…[`LADDER_RUNGS`] − 1, the rung nearest the slope at the interval's start — is exact
///   for the load linearised there, `F(v₀) + c_k (v − v₀)`: the remainder F(v₀) − c_k v₀ is held.
/// - Below the last rung (|v| ≳ 3 v_s: tanh saturated) the whole force is held.
/// - Either is taken only if the velocity ends the interval where that linearisation holds
///   (its slope within one rung, the same sign away from rest); otherwise the interval is
///   stepped again from its start in [`CarriageLoad::substeps`] held steps (λh ≤ 1).
struct LoadedLoop<'a> {
    load: &'a CarriageLoad,
    li: usize,
    steps: usize,
    /// s(0) = F_c / v_s + c_v (N·s/m): the friction's slope at rest.
    c_lin: f64,
    /// The damped interval maps of the ladder and the substep map; `None` when one held step
    /// per interval suffices (`steps` 1: cogging alone, or friction too weak to ring).
    maps: Option<(Vec<nalgebra::DMatrix<f64>>, nalgebra::DMatrix<f64>)>,
}

/// Rungs of the ladder of damped maps of [`LoadedLoop`] (slopes s(0) down to s(0) / 2⁷).
const LADDER_RUNGS: usize = 8;

impl<'a> LoadedLoop<'a> {
    /// From the loop's generator as a function of an extra carriage damper (N·s/m), with the
    /// element bound `limit` of [`bounded_expm`]; `None` when a map is out of bounds.
    fn new(
        load: &'a CarriageLoad,
        li: usize,
        m_eff: f64,
        dt: f64,
        generator: &dyn Fn(f64) -> nalgebra::DMatrix<f64>,
        limit: f64,
    ) -> Option<LoadedLoop<'a>> {
        let steps = load.substeps(m_eff, dt);
        let c_lin = load.friction_n / load.smoothing_m_s + load.viscous_n_s_per_m;
        let maps = if steps == 1 || !(c_lin > 0.0) {
            None
        } else {
            let ladder = (0..LADDER_RUNGS)
                .map(|k| bounded_expm(generator(c_lin * 0.5f64.powi(k as i32)), dt, limit))
                .collect::<Option<Vec<_>>>()?;
            Some((
                ladder,
                bounded_expm(generator(0.0), dt / steps as f64, limit)?,
            ))
        };
        Some(LoadedLoop {
            load,
            li,
            steps: if maps.is_some() { steps } else { 1 },
            c_lin,
            maps,
        })
    }

    /// The slope of the load's force in the velocity (N·s/m) at `v_m_s`.
    fn slope(&self, v_m_s: f64) -> f64 {
        let u = (v_m_s / self.load.smoothing_m_s).cosh();
        self.load.friction_n / (self.load.smoothing_m_s * u * u) + self.load.viscous_n_s_per_m
    }

    /// The ladder's rung for velocity `v_m_s`: the nearest slope (log scale), or
    /// [`LADDER_RUNGS`] below the last.
    fn rung(&self, v_m_s: f64) -> usize {
        let k = (self.c_lin / self.slope(v_m_s)).log2().round();
        if k.is_finite() && k >= 0.0 {
            (k as usize).min(LADDER_RUNGS)
        } else {
            0
        }
    }

    /// One sample interval from `z` (`phi` the whole interval's map without a damper; `tmp`
    /// and `saved` scratch of the state's length).
    fn advance(
        &self,
        phi: &nalgebra::DMatrix<f64>,
        z: &mut [f64],
        tmp: &mut [f64],
        saved: &mut [f64],
    ) {
        let li = self.li;
        let v0 = z[1];
        let Some((ladder, sub)) = &self.maps else {
            z[li] = self.load.force_n(z[0], v0);
            advance(phi, z, tmp);
            return;
        };
        saved.copy_from_slice(z);
        let k = self.rung(v0);
        match ladder.get(k) {
            Some(map) => {
                let c_k = self.c_lin * 0.5f64.powi(k as i32);
                z[li] = self.load.force_n(z[0], v0) - c_k * v0;
                advance(map, z, tmp);
            }
            None => {
                z[li] = self.load.force_n(z[0], v0);
                advance(phi, z, tmp);
            }
        }
        // the linearisation held: the slope at the end within one rung, and no crossing of
        // the stiff band from one side to the other (at rest, k ≤ 1, the band is the map's)
        let k_end = self.rung(z[1]);
        if k_end.abs_diff(k) <= 1 && (k <= 1 || z[1] * v0 > 0.0) {
            return;
        }
        z.copy_from_slice(saved);
        for _ in 0..self.steps {
            z[li] = self.load.force_n(z[0], z[1]);
            advance(sub, z, tmp);
        }
    }
}

/// ω/ω_n of a PID loop (orders 3–4 of [`ServoLaw`]): its pole pair ω over its natural frequency
/// ω_n = √(K_p/M), 1/√(1 + 2ζα) for damping ratio ζ and integral ratio α (both taken ≥ 0);
/// 1 at α = 0, the PD loop.
pub fn pole_pair_ratio(zeta: f64, integral_ratio: f64) -> f64 {
    1.0 / (1.0 + 2.0 * zeta.max(0.0) * integral_ratio.max(0.0)).sqrt()
}

/// A position loop of selectable order (the `servo_lag` candidate), as the command → base
/// transfer function of a rigid carriage (and, coupled, with the beam pushing back):
/// - order 1: a first-order lag with velocity feed-forward, `ẏ = k_v ṙ + ω (r − y)`;
/// - order 2: PD with feed-forward, poles `s² + 2ζωs + ω²` ([`second_order`], [`coupled_servo`]);
/// - order 3: PID with feed-forward, `F/M = k_a r̈ + K_d (k_v ṙ − ẏ) + K_p (r − y) + K_i ∫(r − y)`
///   with the rigid closed-loop poles `(s² + 2ζωs + ω²)(s + αω)`: `K_d = (2ζ + α)ω`,
///   `K_p = (1 + 2ζα)ω²`, `K_i = αω³` (α → 0 is the PD loop); the fitted bandwidth is the
///   natural frequency ω_n = √K_p = ω√(1 + 2ζα) ([`ServoLaw::natural_frequency_rad_s`]), the
///   quantity a PID tuned for a bandwidth sets, so α and ζ shape the loop without moving it;
/// - order 4: the order-3 loop whose drive force follows its command through a first-order lag
///   of time constant β/ω (current loop, digital computation delay): `τ Ḟ = F_c − F`.
///
/// Source: Ellis, *Control System Design Guide* (4th ed., 2012), ch. 17 (position loops with
/// velocity/acceleration feed-forward); the order is chosen by the selection's information
/// criterion among the fitted forms.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ServoLaw {
    /// Order 1–4.
    pub order: usize,
    /// ω (rad/s).
    pub omega: f64,
    /// ζ (orders ≥ 2).
    pub zeta: f64,
    /// Velocity and acceleration feed-forward fractions k_v, k_a.
    pub ff: (f64, f64),
    /// α (orders ≥ 3).
    pub integral_ratio: f64,
    /// β (order 4).
    pub force_lag_ratio: f64,
}

impl ServoLaw {
    /// The law of `p` (`None` without a servo). `p.servo.0` is the loop's natural frequency
    /// ω_n/2π = √(K_p/M)/2π (Hz, [`Params::servo`]); orders 3–4 place their poles at
    /// ω = ω_n/√(1 + 2ζα), since K_p = (1 + 2ζα)ω².
    pub fn of(p: &Params) -> Option<ServoLaw> {
        let (f, z) = p.servo?;
        let order = p.servo_order.clamp(1, 4);
        let integral_ratio = p.servo_integral_ratio.max(0.0);
        let to_pole = if order >= 3 {
            pole_pair_ratio(z, integral_ratio)
        } else {
            1.0
        };
        Some(ServoLaw {
            order,
            omega: 2.0 * std::f64::consts::PI * f * to_pole,
            zeta: z,
            ff: p.servo_ff,
            integral_ratio,
            force_lag_ratio: p.servo_force_lag_ratio.max(0.0),
        })
    }

    /// The loop's natural frequency ω_n = √(K_p/M) (rad/s): the proportional (stiffness) gain
    /// per unit carriage mass, the `servo_bandwidth_hz` the report gives (× 1/2π). It is ω for
    /// orders 1–2 and ω√(1 + 2ζα) for orders 3–4 (the struct's header). A parallel PID tuned
    /// as K_p = Mω_b² has it at its design bandwidth ω_b whatever its integral and derivative
    /// gains, which the pole pair ω alone does not (ω = ω_n/2.2 at α = 2.9, ζ 0.64).
    pub fn natural_frequency_rad_s(&self) -> f64 {
        if self.order >= 3 {
            self.omega / pole_pair_ratio(self.zeta, self.integral_ratio)
        } else {
            self.omega
        }
    }

    /// Largest gain |Y/R(jω)| of the command → base transfer function for a rigid load
    /// (the struct's header; order 1 `(k_v s + ω)/(s + ω)`, orders 2–4
    /// `(k_a s³ + K_d k_v s² + K_p s + K_i) / (τ s⁴ + s³ + K_d s² + K_p s + K_i)` with K_i = 0 and
    /// τ = 0 below order 3 and 4), over 0.01–100 × ω on a log grid of 801 points. A tuned loop
    /// peaks at 1–1.3; the plain second-order loop at ζ 0.3 at 1.75.
    pub fn peak_gain(&self) -> f64 {
        use nalgebra::Complex;
        let w = self.omega;
        let (z, al) = (
            self.zeta,
            if self.order >= 3 {
                self.integral_ratio
            } else {
                0.0
            },
        );
        let (kd, kp, ki) = (
            (2.0 * z + al) * w,
            (1.0 + 2.0 * z * al) * w * w,
            al * w * w * w,
        );
        let tau = if self.order >= 4 {
            self.force_lag_ratio / w
        } else {
            0.0
        };
        let (kv, ka) = self.ff;
        (0..=800)
            .map(|i| {
                let s = Complex::new(0.0, w * 10f64.powf(-2.0 + i as f64 / 200.0));
                let h = if self.order == 1 {
                    (s * kv + w) / (s + w)
                } else {
                    (s * s * s * ka + s * s * (kd * kv) + s * kp + ki)
                        / (s * s * s * s * tau + s * s * s + s * s * kd + s * kp + ki)
                };
                h.norm()
            })
            .fold(0.0, f64::max)
    }

    /// Base position for the command `r` sampled every `dt` s (piecewise linear between
    /// samples), coupled to the beam of `c` when given (the loop force then acts on the
    /// carriage, eq. 5 in modal form), else for a rigid load. Orders 2–4 carry the carriage
    /// `load` as well (friction and cogging the loop must overcome, [`CarriageLoad`]): in N
    /// with a beam, per unit moving mass (N/kg, [`CarriageLoad::per_unit_mass`]) without;
    /// order 1 has no mass to load.
    pub fn respond(
        &self,
        r: &[f64],
        dt: f64,
        c: Option<&BeamCache>,
        load: Option<&CarriageLoad>,
    ) -> Vec<f64> {
        match (self.order, c, load) {
            (1, _, _) => first_order(r, dt, self.omega, self.ff.0),
            (2, None, None) => second_order(
                r,
                dt,
                self.omega,
                self.zeta,
                1.0 - self.ff.0,
                1.0 - self.ff.1,
            ),
            (2, Some(c), _) => coupled_servo(r, dt, self.omega, self.zeta, self.ff, c, load),
            // a loaded rigid PD loop is the PID loop without integral action
            _ => self.pid(r, dt, c, load),
        }
    }

    /// Orders 3–4 (state space, exact per sample by one matrix exponential; a carriage `load`
    /// is stepped by [`LoadedLoop`]).
    fn pid(
        &self,
        r: &[f64],
        dt: f64,
        c: Option<&BeamCache>,
        load: Option<&CarriageLoad>,
    ) -> Vec<f64> {
        let n = r.len();
        let nm = c.map_or(0, |c| c.omega.len());
        let generator = |damper: f64| self.pid_generator(c, load.is_some(), damper);
        let (a, g, tau) = generator(0.0);
        // the drive-force row scales as ω³/β (m/s² per state unit): a larger element bound than
        // the root transition's, still finite
        let Some(phi) = bounded_expm(a, dt, 1e10) else {
            return vec![f64::NAN; n];
        };
        let lag = tau > 0.0;
        let dim = phi.nrows();
        let (fi, ri, vi) = (3 + 2 * nm, dim - 2, dim - 1);
        let m_eff = c.map_or(1.0, |c| c.total_mass) / g;
        let loaded = match load {
            Some(l) => match LoadedLoop::new(l, dim - 3, m_eff, dt, &|d| generator(d).0, 1e10) {
                Some(ll) => Some(ll),
                None => return vec![f64::NAN; n],
            },
            None => None,
        };
        let mut saved = vec![0.0; dim];
        let gamma: &[f64] = c.map_or(&[], |c| &c.gamma);
        let (mut zv, mut tmp) = (vec![0.0; dim], vec![0.0; dim]);
        zv[0] = r[0];
        let mut y = Vec::with_capacity(n);
        let mut v_prev = 0.0;
        for k in 0..n {
            y.push(zv[0]);
            let v = if k + 1 < n {
                (r[k + 1] - r[k]) / dt
            } else {
                0.0
            };
            // acceleration feed-forward of the velocity step at this sample: an impulse of
            // force (through the drive lag when there is one)
            let imp = self.ff.1 * (v - v_prev);
            if lag {
                zv[fi] += imp / tau;
            } else {
                zv[1] += g * imp;
                for j in 0..nm {
                    zv[3 + 2 * j] -= gamma[j] * g * imp;
                }
            }
            v_prev = v;
            zv[ri] = r[k];
            zv[vi] = v;
            match &loaded {
                Some(ll) => ll.advance(&phi, &mut zv, &mut tmp, &mut saved),
                None => advance(&phi, &mut zv, &mut tmp),
            }
            if !zv[0].is_finite() {
                y.extend(std::iter::repeat(f64::NAN).take(n - y.len()));
                break;
            }
        }
        y
    }

    /// The generator A of the order-3/4 loop (state `[y, ẏ, (η_j, η̇_j)…, ∫(r − y), F?,
    /// F_load?, r, ṙ]`, the load's force present with `loaded`) with an extra carriage damper
    /// (N·s/m), the ratio g = M / (M − ΣΓ²) of the force on the carriage to its acceleration
    /// per unit moving mass, and the drive lag τ (0 without).
    fn pid_generator(
        &self,
        c: Option<&BeamCache>,
        loaded: bool,
        damper: f64,
    ) -> (nalgebra::DMatrix<f64>, f64, f64) {
        let nm = c.map_or(0, |c| c.omega.len());
        let (m_tot, sum_g2) = c.map_or((1.0, 0.0), |c| {
            (c.total_mass, c.gamma.iter().map(|g| g * g).sum())
        });
        let m_eff = (m_tot - sum_g2).max(1e-9 * m_tot);
        let g = m_tot / m_eff;
        let (w, z, al) = (self.omega, self.zeta, self.integral_ratio);
        let (kd, kp, ki) = (
            (2.0 * z + al) * w,
            (1.0 + 2.0 * z * al) * w * w,
            al * w * w * w,
        );
        let lag = self.order >= 4 && self.force_lag_ratio > 0.0;
        let tau = if lag { self.force_lag_ratio / w } else { 0.0 };
        let ii = 2 + 2 * nm;
        let fi = ii + 1;
        let dim = ii + 1 + usize::from(lag) + usize::from(loaded) + 2;
        let (ri, vi) = (dim - 2, dim - 1);
        // the commanded force per unit moving mass (without the r̈ feed-forward impulses)
        let mut uc = vec![0.0; dim];
        uc[0] = -kp;
        uc[1] = -kd;
        uc[ii] = ki;
        uc[ri] = kp;
        uc[vi] = kd * self.ff.0;
        let mut acc_row = vec![0.0; dim];
        if lag {
            acc_row[fi] = g;
        } else {
            for i in 0..dim {
                acc_row[i] = g * uc[i];
            }
        }
        if loaded {
            acc_row[dim - 3] = -1.0 / m_eff;
        }
        acc_row[1] -= damper / m_eff;
        let mut a = root_generator(&mut acc_row, m_eff, c);
        a[(ii, 0)] = -1.0;
        a[(ii, ri)] = 1.0;
        if lag {
            for i in 0..dim {
                a[(fi, i)] = uc[i] / tau;
            }
            a[(fi, fi)] -= 1.0 / tau;
        }
        (a, g, tau)
    }
}

/// y = r + e with `ė + ωe = −(1 − k_v) ṙ` (a first-order lag with velocity feed-forward k_v),
/// exact for a piecewise-linear r.
pub(crate) fn first_order(r: &[f64], dt: f64, omega: f64, kv: f64) -> Vec<f64> {
    let a = (-omega * dt).exp();
    let b = if omega * dt > 1e-12 {
        (1.0 - a) / omega
    } else {
        dt
    };
    let n = r.len();
    let mut e = 0.0;
    let mut y = Vec::with_capacity(n);
    for k in 0..n {
        y.push(r[k] + e);
        let v = if k + 1 < n {
            (r[k + 1] - r[k]) / dt
        } else {
            0.0
        };
        e = at_rest(a * e - (1.0 - kv) * v * b);
    }
    y
}

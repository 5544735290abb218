//! The truth plant: carriage + digital servo + optional mount + FE beam + sensors, integrated
//! with classical RK4 at a fine step (default 40 steps per output sample).
//!
//! Equations (coordinates: motor/carriage position y_m, beam-root position y_r, FE modal
//! coordinates η_r of [`super::fe::FeModes`], Rayleigh damping from ζ1, ζ2):
//! - beam (FE form of the paper's eq. 12 in the moving frame):
//!   `η̈_r + 2ζ_rω_r η̇_r + ω_r² η_r = −Γ_r ÿ_r + Σ_j φ_r(x_j) F_j`, with the distributed quadratic
//!   air drag `F_j = −c_d L_j |v_j| v_j` on node j (tributary length L_j, absolute velocity v_j),
//!   or a drag `−c_t |v| v` on a body at the tip (the tip node alone);
//! - beam root (mass m_root, the whole carriage without a mount):
//!   `(m_root + m_b − ΣΓ_r²) ÿ_r = F_root + ΣF_j − Σ Γ_r (Σ_j φ_r(x_j)F_j − 2ζ_rω_rη̇_r − ω_r²η_r)`;
//! - without a mount F_root = F_motor − F_friction(ẏ) − F_cogging(y) and y_m = y_r; with a mount
//!   the motor mass m₁ obeys `m₁ÿ_m = F_motor − F_friction − F_cogging − k(y_m − y_r) − c(ẏ_m − ẏ_r)`
//!   and F_root = k(y_m − y_r) + c(ẏ_m − ẏ_r);
//! - backlash instead of a mount: the motor mass m₁ drives the beam-root block m_r through a
//!   stiff contact with a gap of total width b: `F_c = k_c p + c_c (ẏ_m − ẏ_r)` while in contact
//!   (penetration p = (y_m − y_r) ∓ b/2 beyond the gap, compressive only), 0 inside the gap; the
//!   block rides on a guide with Coulomb friction (tanh-smoothed), which holds it inside the gap:
//!   F_root = F_c − F_g tanh(ẏ_r / v_s);
//! - a cubic clamp: the compliant root (FE rotation θ₀) has the moment k_r θ₀ + k₃ θ₀³; the
//!   linear part is in the modes, the cubic one M₃ = k₃ θ₀³ a modal force `−θ₀,r M₃` (internal:
//!   no net force on the carriage). The modes above the fine step's reach answer M₃
//!   quasi-statically (static correction: K⁻¹ less the kept modes' Σ θ₀,r²/ω_r²), so
//!   θ₀ = Σ θ₀,r η_r − c M₃(θ₀), solved per evaluation, and the tip moves by the same
//!   correction (Craig & Kurdila, *Fundamentals of Structural Dynamics*, §14.5);
//! - friction: Coulomb (tanh-smoothed over `stribeck_m_s`) + viscous; cogging `A sin(2π y/p + φ)`;
//! - servo: cascaded position P / velocity PI loop evaluated once per fine step (zero-order
//!   hold), with velocity and acceleration feed-forward (off when the concealed effect is a slow
//!   servo), the standard industrial drive structure (Ellis, *Control System Design Guide*,
//!   ch. 17).

use super::fe::FeModes;

/// Friction on the carriage.
#[derive(Clone, Copy, Debug, Default)]
pub struct Friction {
    /// Coulomb level (N).
    pub coulomb_n: f64,
    /// Viscous coefficient (N·s/m).
    pub viscous_n_s_per_m: f64,
    /// Velocity over which the Coulomb term is smoothed (m/s).
    pub stribeck_m_s: f64,
}

/// Carriage–beam mount resonance.
#[derive(Clone, Copy, Debug)]
pub struct Mount {
    /// Mount (beam-side) mass m₂ (kg), part of the carriage mass.
    pub mass_kg: f64,
    /// √(k/(m₂ + m_beam))/2π (Hz).
    pub freq_hz: f64,
    /// Damping ratio of that resonance.
    pub zeta: f64,
}

/// Play in the drive between the motor and the beam-root block.
#[derive(Clone, Copy, Debug)]
pub struct Backlash {
    /// Total gap (m).
    pub gap_m: f64,
    /// Beam-root block mass m_r (kg), part of the carriage mass.
    pub block_mass_kg: f64,
    /// Contact stiffness (N/m).
    pub contact_n_per_m: f64,
    /// Contact damping (N·s/m), only while in contact.
    pub contact_damping_n_s_per_m: f64,
    /// Guide friction on the block (N).
    pub guide_friction_n: f64,
    /// Velocity over which the guide friction is smoothed (m/s).
    pub guide_stribeck_m_s: f64,
}

impl Backlash {
    /// Lost motion (m): the carriage travel between dragging the block one way and the other
    /// while the guide friction loads the contact, `gap + 2 F_g / k_c`. The contact deflects by
    /// F_g / k_c on each side, so this — not the geometric gap — is the width of the dead band
    /// the recordings show (the `backlash_m` of the diagnosis' play operator).
    pub fn lost_motion_m(&self) -> f64 {
        self.gap_m + 2.0 * self.guide_friction_n / self.contact_n_per_m
    }

    /// Contact force on the block (N) for motor − block displacement `d` and velocity `dv`.
    pub fn contact_force(&self, d: f64, dv: f64) -> f64 {
        let h = 0.5 * self.gap_m;
        let pen = if d > h {
            d - h
        } else if d < -h {
            d + h
        } else {
            return 0.0;
        };
        let f = self.contact_n_per_m * pen + self.contact_damping_n_s_per_m * dv;
        // a contact pushes, never pulls
        if pen > 0.0 {
            f.max(0.0)
        } else {
            f.min(0.0)
        }
    }
}

/// Servo loop.
#[derive(Clone, Copy, Debug)]
pub struct Servo {
    /// Position-loop bandwidth Kp (Hz).
    pub position_bandwidth_hz: f64,
    /// Velocity-loop bandwidth (Hz).
    pub velocity_bandwidth_hz: f64,
    /// Velocity and acceleration feed-forward on.
    pub feedforward: bool,
}

impl Servo {
    /// The loop's natural frequency √(K_p/M)/2π (Hz), the diagnosis' `servo_bandwidth_hz`
    /// (`diagnose::model::ServoLaw::natural_frequency_rad_s`). With the gains of
    /// `Plant::servo_gains` (velocity gain M ω_v, its integral M ω_v²/4, position gain ω_p)
    /// the rigid closed loop has the characteristic polynomial
    /// `M s³ + Mω_v s² + M(ω_v ω_p + ω_v²/4) s + M ω_v² ω_p/4`, whose proportional coefficient
    /// gives ω_n² = ω_v ω_p + ω_v²/4 (2√2 ω_p at ω_v = 4ω_p).
    pub fn natural_frequency_hz(&self) -> f64 {
        let (fp, fv) = (self.position_bandwidth_hz, self.velocity_bandwidth_hz);
        (fv * fp + 0.25 * fv * fv).sqrt()
    }
}

/// Sensor models.
#[derive(Clone, Copy, Debug)]
pub struct Sensors {
    /// Tip camera noise σ (m), quantum (m), latency (s).
    pub tip_noise_m: f64,
    /// Tip quantum (m).
    pub tip_quantum_m: f64,
    /// Tip latency (s).
    pub tip_delay_s: f64,
    /// Tip scale: the camera reports `tip_gain × position` (calibration error; 1 = exact).
    pub tip_gain: f64,
    /// Encoder noise σ (m).
    pub encoder_noise_m: f64,
    /// Encoder quantum (m).
    pub encoder_quantum_m: f64,
    /// Force noise σ (N).
    pub force_noise_n: f64,
    /// Force quantum (N).
    pub force_quantum_n: f64,
}

/// The whole plant.
#[derive(Clone, Debug)]
pub struct Plant {
    /// FE beam modes (None: carriage only) and node spacing (m).
    pub beam: Option<(FeModes, f64)>,
    /// Damping ratios of the first two beam modes (Rayleigh for the rest).
    pub zeta: (f64, f64),
    /// Carriage mass without the beam (kg), incl. a mount mass.
    pub carriage_mass_kg: f64,
    /// Mass the feed-forward assumes (kg).
    pub feedforward_mass_kg: f64,
    /// Servo.
    pub servo: Servo,
    /// Friction.
    pub friction: Friction,
    /// Cogging (amplitude N, pitch m, phase rad).
    pub cogging: Option<(f64, f64, f64)>,
    /// Mount.
    pub mount: Option<Mount>,
    /// Play between motor and beam root (exclusive with `mount`).
    pub backlash: Option<Backlash>,
    /// Cubic clamp stiffness k₃ (N·m/rad³; needs a compliant root in the FE beam).
    pub cubic_root_nm_per_rad3: f64,
    /// Distributed quadratic drag coefficient (N·s²/m³ = kg/m², force per unit length).
    pub drag_kg_per_m2: f64,
    /// Quadratic drag on a body at the tip (kg/m: force = −c |v| v on the tip node).
    pub tip_drag_kg_per_m: f64,
    /// Sensors.
    pub sensors: Sensors,
}

/// Clean (noise-free) fine-grid output of a run.
#[derive(Clone, Debug)]
pub struct FineRun {
    /// Motor position (m).
    pub y_motor_m: Vec<f64>,
    /// Absolute tip position (m) (= root position without beam).
    pub tip_m: Vec<f64>,
    /// Motor force (N).
    pub force_n: Vec<f64>,
    /// Root rotation of the clamp (rad) (0 for a rigid clamp or without a beam).
    pub root_rot_rad: Vec<f64>,
}

impl Plant {
    /// Runs the command `cmd` = (position m, velocity m/s, acceleration m/s²) per fine step `dt`.
    pub fn run(&self, cmd: &[(f64, f64, f64)], dt: f64) -> FineRun {
        let dy = self.dynamics();
        let nm = dy.nm;
        let (wp, kv, kiv) = self.servo_gains(dy.m_b);
        // state: y_m, v_m, y_r, v_r, eta.., etad..
        let ns = 4 + 2 * nm;
        let mut x = vec![0.0; ns];
        x[0] = cmd[0].0;
        x[2] = cmd[0].0;
        let mut integ = 0.0;
        let mut out = FineRun {
            y_motor_m: vec![],
            tip_m: vec![],
            force_n: vec![],
            root_rot_rad: vec![],
        };
        let mut rk = Rk4::new(ns);
        let ff = if self.servo.feedforward { 1.0 } else { 0.0 };
        for &(r, rv, ra) in cmd {
            // digital cascaded servo (ZOH over the step)
            let (ym, vm) = (x[0], x[1]);
            let v_ref = wp * (r - ym) + ff * rv;
            let ev = v_ref - vm;
            integ += ev * dt;
            let u = ff * self.feedforward_mass_kg * ra + kv * ev + kiv * integ;
            // record outputs at the step start
            let mut tip = x[2];
            if let Some(m) = dy.modes {
                for rr in 0..nm {
                    tip += m.node_w[rr][dy.nodes - 1] * x[4 + rr];
                }
            }
            let (theta, m3) = dy.clamp_rotation(&x);
            out.y_motor_m.push(ym);
            out.tip_m.push(tip - dy.residual.1 * m3);
            out.force_n.push(u);
            out.root_rot_rad.push(theta);
            rk.step(&mut x, dt, |z, dz| dy.deriv(z, u, dz));
        }
        out
    }

    /// The cascaded loop's gains for a beam of mass `m_b` (kg): position gain ω_p (1/s),
    /// velocity gain k_v (N·s/m) and its integral gain k_iv (N/m).
    fn servo_gains(&self, m_b: f64) -> (f64, f64, f64) {
        let total = self.carriage_mass_kg + m_b;
        let wp = 2.0 * std::f64::consts::PI * self.servo.position_bandwidth_hz;
        let wv = 2.0 * std::f64::consts::PI * self.servo.velocity_bandwidth_hz;
        (wp, total * wv, total * wv * wv / 4.0)
    }

    /// The mount's resonance (Hz) as the rig shows it: the undamped natural frequency |λ|/2π
    /// of the closed-loop plant linearised at rest (the servo holding its position as a
    /// continuous loop; friction, cogging, drag and the cubic clamp off) whose mode has the
    /// largest share of its strain energy in the mount spring. The servo is a spring and
    /// damper of finite stiffness on the motor mass, so this is not the resonance with the
    /// carriage held ([`crate::model::mount::coupled_resonance_hz`]; docs/diagnose.md,
    /// "Session 28"). `None` without a mount.
    pub fn mount_resonance_hz(&self) -> Option<f64> {
        use nalgebra::{Complex, DMatrix, DVector};
        self.mount?;
        let linear = Plant {
            friction: Friction::default(),
            cogging: None,
            cubic_root_nm_per_rad3: 0.0,
            drag_kg_per_m2: 0.0,
            tip_drag_kg_per_m: 0.0,
            ..self.clone()
        };
        let dy = linear.dynamics();
        let (wp, kv, kiv) = linear.servo_gains(dy.m_b);
        // state [x of `deriv`, ∫ velocity error]; linear, so a unit column is exact
        let n = 4 + 2 * dy.nm + 1;
        let mut a = DMatrix::<f64>::zeros(n, n);
        let (mut x, mut dx) = (vec![0.0; n - 1], vec![0.0; n - 1]);
        for j in 0..n {
            x.iter_mut().for_each(|v| *v = 0.0);
            let integ = if j == n - 1 { 1.0 } else { 0.0 };
            if j < n - 1 {
                x[j] = 1.0;
            }
            let ev = -wp * x[0] - x[1];
            dy.deriv(&x, kv * ev + kiv * integ, &mut dx);
            for i in 0..n - 1 {
                a[(i, j)] = dx[i];
            }
            a[(n - 1, j)] = ev;
        }
        let ac = a.map(|v| Complex::new(v, 0.0));
        let mut best: Option<(f64, f64)> = None;
        for lam in a.complex_eigenvalues().iter().filter(|l| l.im > 0.0) {
            // its eigenvector by inverse iteration at a shift just off λ
            let shift = lam * Complex::new(1.0 + 1e-9, 1e-9);
            let lu = (&ac - DMatrix::identity(n, n) * shift).lu();
            let mut v = DVector::from_element(n, Complex::new(1.0, 0.0));
            for _ in 0..3 {
                v = lu.solve(&v)?;
                v /= Complex::new(v.norm(), 0.0);
            }
            let mount = dy.k_m * (v[0] - v[2]).norm_sqr();
            let beam: f64 = dy.modes.map_or(0.0, |m| {
                (0..dy.nm)
                    .map(|r| m.omega_rad_s[r].powi(2) * v[4 + r].norm_sqr())
                    .sum()
            });
            // the loop is a spring too: k_v ω_p on the motor, k_iv on its integral
            let servo = kv * wp * v[0].norm_sqr() + kiv * v[n - 1].norm_sqr();
            let share = mount / (mount + beam + servo).max(1e-300);
            if best.map_or(true, |(s, _)| share > s) {
                best = Some((share, lam.norm() / (2.0 * std::f64::consts::PI)));
            }
        }
        best.map(|(_, f)| f)
    }

    /// The constants of this plant's equations of motion (module header).
    fn dynamics(&self) -> Dynamics<'_> {
        let (nm, modes, h) = match &self.beam {
            Some((m, h)) => (m.omega_rad_s.len(), Some(m), *h),
            None => (0, None, 0.0),
        };
        let m_b = modes.map_or(0.0, |m| m.beam_mass_kg);
        let sum_g2: f64 = modes.map_or(0.0, |m| m.participation.iter().map(|g| g * g).sum());
        let zetas: Vec<f64> = match modes {
            Some(m) => {
                let (w1, w2) = (
                    m.omega_rad_s[0],
                    *m.omega_rad_s.get(1).unwrap_or(&(m.omega_rad_s[0] * 6.0)),
                );
                let det = w2 / w1 - w1 / w2;
                let a1 = 2.0 * (self.zeta.0 * w2 - self.zeta.1 * w1) / det;
                let a2 = 2.0 * (self.zeta.1 / w1 - self.zeta.0 / w2) / det;
                m.omega_rad_s
                    .iter()
                    .map(|w| 0.5 * (a1 / w + a2 * w))
                    .collect()
            }
            None => vec![],
        };
        let nodes = modes.map_or(0, |m| m.node_w[0].len());
        let trib: Vec<f64> = (0..nodes)
            .map(|j| {
                if j == 0 {
                    0.0
                } else if j + 1 == nodes {
                    0.5 * h
                } else {
                    h
                }
            })
            .collect();
        let (m1, m_root, k_m, c_m) = match (self.mount, self.backlash) {
            (_, Some(b)) => (
                self.carriage_mass_kg - b.block_mass_kg,
                b.block_mass_kg,
                0.0,
                0.0,
            ),
            (Some(mt), None) => {
                let w = 2.0 * std::f64::consts::PI * mt.freq_hz;
                let k = w * w * (mt.mass_kg + m_b);
                (
                    self.carriage_mass_kg - mt.mass_kg,
                    mt.mass_kg,
                    k,
                    2.0 * mt.zeta * w * (mt.mass_kg + m_b),
                )
            }
            (None, None) => (0.0, self.carriage_mass_kg, 0.0, 0.0),
        };
        Dynamics {
            plant: self,
            modes,
            nm,
            nodes,
            trib,
            zetas,
            root_theta: modes.map_or(&[], |m| &m.root_theta),
            residual: modes.map_or((0.0, 0.0), residual_flexibility),
            m_b,
            sum_g2,
            m1,
            m_root,
            k_m,
            c_m,
            coupled: self.mount.is_some() || self.backlash.is_some(),
        }
    }
}

/// The quasi-static root rotation (rad / N·m) and tip deflection (m / N·m) per unit clamp
/// moment of the modes `m` leaves out: the static response less the kept modes' Σ θ₀,r²/ω_r²
/// and Σ w_tip,r θ₀,r/ω_r² (module header).
fn residual_flexibility(m: &FeModes) -> (f64, f64) {
    let (root, tip) = m.root_moment_static;
    let last = m.node_w[0].len() - 1;
    let (mut kept_root, mut kept_tip) = (0.0, 0.0);
    for r in 0..m.omega_rad_s.len() {
        let w2 = m.omega_rad_s[r] * m.omega_rad_s[r];
        kept_root += m.root_theta[r] * m.root_theta[r] / w2;
        kept_tip += m.root_theta[r] * m.node_w[r][last] / w2;
    }
    ((root - kept_root).max(0.0), tip - kept_tip)
}

/// The equations of motion of one [`Plant::run`] (module header), state
/// `[y_m, v_m, y_r, v_r, η…, η̇…]`.
struct Dynamics<'a> {
    plant: &'a Plant,
    modes: Option<&'a FeModes>,
    nm: usize,
    nodes: usize,
    /// Tributary length of each node (m).
    trib: Vec<f64>,
    /// Damping ratio of each mode (Rayleigh from ζ1, ζ2).
    zetas: Vec<f64>,
    /// Root rotation per modal coordinate.
    root_theta: &'a [f64],
    /// Quasi-static root rotation (rad / N·m) and tip deflection (m / N·m) of the modes left
    /// out, per unit clamp moment (module header).
    residual: (f64, f64),
    m_b: f64,
    sum_g2: f64,
    /// Motor mass (with a mount or play), root mass, mount stiffness and damping.
    m1: f64,
    m_root: f64,
    k_m: f64,
    c_m: f64,
    /// Motor and root are separate bodies (mount or play).
    coupled: bool,
}

impl Dynamics<'_> {
    fn friction(&self, v: f64) -> f64 {
        let f = &self.plant.friction;
        if f.coulomb_n == 0.0 && f.viscous_n_s_per_m == 0.0 {
            0.0
        } else {
            f.coulomb_n * (v / f.stribeck_m_s.max(1e-9)).tanh() + f.viscous_n_s_per_m * v
        }
    }

    fn cogging(&self, y: f64) -> f64 {
        match self.plant.cogging {
            Some((a, p, ph)) => a * (2.0 * std::f64::consts::PI * y / p + ph).sin(),
            None => 0.0,
        }
    }

    /// Modal forces of the drag on the nodes and of the cubic clamp into `modal_f`; returns
    /// the total drag force (N).
    fn modal_forces(&self, x: &[f64], modal_f: &mut [f64]) -> f64 {
        let (nm, vr) = (self.nm, x[3]);
        let mut drag_total = 0.0;
        let dragged = self.plant.drag_kg_per_m2 > 0.0 || self.plant.tip_drag_kg_per_m > 0.0;
        if let Some(m) = self.modes.filter(|_| dragged) {
            let tip = self.nodes - 1;
            for j in 1..self.nodes {
                let c = self.plant.drag_kg_per_m2 * self.trib[j]
                    + if j == tip {
                        self.plant.tip_drag_kg_per_m
                    } else {
                        0.0
                    };
                if c > 0.0 {
                    let mut v = vr;
                    for r in 0..nm {
                        v += m.node_w[r][j] * x[4 + nm + r];
                    }
                    let f = -c * v.abs() * v;
                    drag_total += f;
                    for r in 0..nm {
                        modal_f[r] += m.node_w[r][j] * f;
                    }
                }
            }
        }
        if self.plant.cubic_root_nm_per_rad3 != 0.0 {
            let (_, m3) = self.clamp_rotation(x);
            for r in 0..nm {
                modal_f[r] -= self.root_theta[r] * m3;
            }
        }
        drag_total
    }

    /// The clamp's rotation θ₀ (rad) and cubic moment M₃ = k₃ θ₀³ (N·m) in state `x`: the
    /// root of θ₀ + c k₃ θ₀³ = Σ θ₀,r η_r (c the modes left out, module header), by Newton
    /// from the kept modes' rotation.
    fn clamp_rotation(&self, x: &[f64]) -> (f64, f64) {
        let k3 = self.plant.cubic_root_nm_per_rad3;
        let kept: f64 = (0..self.nm).map(|r| self.root_theta[r] * x[4 + r]).sum();
        let c = self.residual.0;
        let mut theta = kept;
        for _ in 0..20 {
            let g = theta + c * k3 * theta.powi(3) - kept;
            let step = g / (1.0 + 3.0 * c * k3 * theta * theta).max(0.05);
            theta -= step;
            if step.abs() <= 1e-13 * theta.abs() {
                break;
            }
        }
        (theta, k3 * theta.powi(3))
    }

    /// The force on the root (N) and the motor acceleration (m/s², NaN when motor and root
    /// are one body) for motor force `u`.
    fn root_force(&self, x: &[f64], u: f64) -> (f64, f64) {
        let (ym, vm, yr, vr) = (x[0], x[1], x[2], x[3]);
        let dist = self.friction(vm) + self.cogging(ym);
        if let Some(b) = &self.plant.backlash {
            let fc = b.contact_force(ym - yr, vm - vr);
            let guide = b.guide_friction_n * (vr / b.guide_stribeck_m_s.max(1e-9)).tanh();
            (fc - guide, (u - dist - fc) / self.m1)
        } else if self.plant.mount.is_some() {
            let fs = self.k_m * (ym - yr) + self.c_m * (vm - vr);
            (fs, (u - dist - fs) / self.m1)
        } else {
            (u - dist, f64::NAN)
        }
    }

    /// dx/dt for motor force `u`.
    fn deriv(&self, x: &[f64], u: f64, dx: &mut [f64]) {
        let nm = self.nm;
        let mut modal_f = [0.0f64; 16];
        let drag_total = self.modal_forces(x, &mut modal_f);
        let (f_root, a_m) = self.root_force(x, u);
        let mut rhs = f_root + drag_total;
        if let Some(m) = self.modes {
            for r in 0..nm {
                let w = m.omega_rad_s[r];
                rhs -= m.participation[r]
                    * (modal_f[r] - 2.0 * self.zetas[r] * w * x[4 + nm + r] - w * w * x[4 + r]);
            }
        }
        let a_r = rhs / (self.m_root + self.m_b - self.sum_g2);
        dx[2] = x[3];
        dx[3] = a_r;
        if self.coupled {
            dx[0] = x[1];
            dx[1] = a_m;
        } else {
            dx[0] = x[3];
            dx[1] = a_r;
        }
        if let Some(m) = self.modes {
            for r in 0..nm {
                let w = m.omega_rad_s[r];
                dx[4 + r] = x[4 + nm + r];
                dx[4 + nm + r] = -m.participation[r] * a_r + modal_f[r]
                    - 2.0 * self.zetas[r] * w * x[4 + nm + r]
                    - w * w * x[4 + r];
            }
        }
    }
}

/// Classical fourth-order Runge–Kutta with reused scratch vectors.
struct Rk4 {
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
}

impl Rk4 {
    fn new(n: usize) -> Rk4 {
        Rk4 {
            k: std::array::from_fn(|_| vec![0.0; n]),
            tmp: vec![0.0; n],
        }
    }

    /// x ← x + one step of `dt` of dx/dt = f(x).
    fn step(&mut self, x: &mut [f64], dt: f64, f: impl Fn(&[f64], &mut [f64])) {
        let n = x.len();
        let [k1, k2, k3, k4] = &mut self.k;
        f(x, k1);
        for i in 0..n {
            self.tmp[i] = x[i] + 0.5 * dt * k1[i];
        }
        f(&self.tmp, k2);
        for i in 0..n {
            self.tmp[i] = x[i] + 0.5 * dt * k2[i];
        }
        f(&self.tmp, k3);
        for i in 0..n {
            self.tmp[i] = x[i] + dt * k3[i];
        }
        f(&self.tmp, k4);
        for i in 0..n {
            x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (position, velocity, acceleration) of cosine-ramp moves between `stops` (m), each over
    /// `t_move` s followed by a `t_hold` s dwell, at fine step `dt`.
    fn moves(stops: &[f64], t_move: f64, t_hold: f64, dt: f64) -> Vec<(f64, f64, f64)> {
        let pi = std::f64::consts::PI;
        let mut out = Vec::new();
        for w in stops.windows(2) {
            let (a, b) = (w[0], w[1]);
            let n = (t_move / dt) as usize;
            for k in 0..n {
                let ph = pi * k as f64 * dt / t_move;
                let h = 0.5 * (b - a);
                out.push((
                    a + h * (1.0 - ph.cos()),
                    h * pi / t_move * ph.sin(),
                    h * (pi / t_move).powi(2) * ph.cos(),
                ));
            }
            out.extend(std::iter::repeat((b, 0.0, 0.0)).take((t_hold / dt) as usize));
        }
        out
    }

    fn carriage_with_play(gap: f64) -> Plant {
        Plant {
            beam: None,
            zeta: (0.01, 0.01),
            carriage_mass_kg: 2.0,
            feedforward_mass_kg: 2.0,
            servo: Servo {
                position_bandwidth_hz: 40.0,
                velocity_bandwidth_hz: 150.0,
                feedforward: true,
            },
            friction: Friction::default(),
            cogging: None,
            mount: None,
            backlash: Some(Backlash {
                gap_m: gap,
                block_mass_kg: 0.5,
                contact_n_per_m: (2.0 * std::f64::consts::PI * 150.0f64).powi(2) * 0.5,
                contact_damping_n_s_per_m: 2.0 * 0.3 * 2.0 * std::f64::consts::PI * 150.0 * 0.5,
                guide_friction_n: 5.0,
                guide_stribeck_m_s: 2e-3,
            }),
            cubic_root_nm_per_rad3: 0.0,
            drag_kg_per_m2: 0.0,
            tip_drag_kg_per_m: 0.0,
            sensors: Sensors {
                tip_noise_m: 0.0,
                tip_quantum_m: 0.0,
                tip_delay_s: 0.0,
                tip_gain: 1.0,
                encoder_noise_m: 0.0,
                encoder_quantum_m: 0.0,
                force_noise_n: 0.0,
                force_quantum_n: 0.0,
            },
        }
    }

    #[test]
    fn a_mounts_resonance_is_the_closed_loops_and_the_held_one_only_for_a_stiff_loop() {
        // a 0.9 m steel strip on a 0.8 kg mount (rigid-beam 46 Hz) on a 3.4 kg carriage: with
        // the carriage held the mount + beam resonate at `coupled_resonance_hz`; the loop
        // holds it with a finite spring and damper, so the rig shows another frequency; a loop
        // 30× stiffer gives the held one back (the loop's own heavily damped mode of the motor
        // against the mount is never the one reported)
        let beam = super::super::fe::FeBeam {
            length_m: 0.9,
            density_kg_m3: 8190.0,
            youngs_modulus_pa: 1.9e11,
            width_m: (0.025, 0.025),
            thickness_m: (0.0015, 0.0015),
            tip_mass_kg: 0.0,
            root_stiffness_nm_per_rad: None,
            gravity_sign: 0.0,
            elements: 24,
        };
        let modes = beam.modes(6).unwrap();
        let mount = Mount {
            mass_kg: 0.8,
            freq_hz: 46.0,
            zeta: 0.04,
        };
        let k = (2.0 * std::f64::consts::PI * 46.0f64).powi(2) * (0.8 + modes.beam_mass_kg);
        let held = crate::model::mount::coupled_resonance_hz(
            k,
            0.8,
            modes.beam_mass_kg,
            &modes.participation,
            &modes.omega_rad_s,
        )
        .unwrap();
        let plant = |pos_hz: f64, vel_hz: f64| Plant {
            beam: Some((modes.clone(), 0.9 / 24.0)),
            zeta: (0.01, 0.005),
            carriage_mass_kg: 3.4,
            mount: Some(mount),
            backlash: None,
            servo: Servo {
                position_bandwidth_hz: pos_hz,
                velocity_bandwidth_hz: vel_hz,
                feedforward: true,
            },
            ..carriage_with_play(0.0)
        };
        let real = plant(45.0, 150.0).mount_resonance_hz().unwrap();
        let stiff = plant(1350.0, 4500.0).mount_resonance_hz().unwrap();
        assert!(
            (stiff / held - 1.0).abs() < 0.01,
            "stiff loop {stiff} Hz, held {held} Hz"
        );
        assert!(
            (real / held - 1.0).abs() > 0.01,
            "real loop {real} Hz, held {held} Hz"
        );
        assert!(
            (real / held - 1.0).abs() < 0.2,
            "real loop {real} Hz, held {held} Hz"
        );
        assert!(Plant {
            mount: None,
            ..plant(45.0, 150.0)
        }
        .mount_resonance_hz()
        .is_none());
    }

    #[test]
    fn a_dragged_block_trails_by_half_the_lost_motion_not_half_the_gap() {
        // at constant speed the contact carries the guide friction and deflects by F_g / k_c:
        // the dead band the recordings show is the lost motion gap + 2 F_g / k_c (2.3 % more
        // than this gap), which is what the truth reports as `backlash_m`
        let gap = 1e-3;
        let dt = 1.0 / 4000.0;
        let v = 0.05;
        let cmd: Vec<(f64, f64, f64)> = (0..8000).map(|k| (v * k as f64 * dt, v, 0.0)).collect();
        let plant = carriage_with_play(gap);
        let b = plant.backlash.unwrap();
        let run = plant.run(&cmd, dt);
        let k = 7900;
        let offset = run.y_motor_m[k] - run.tip_m[k];
        assert!(
            (offset - 0.5 * b.lost_motion_m()).abs() < 2e-3 * gap,
            "offset {offset}, half lost motion {}",
            0.5 * b.lost_motion_m()
        );
        assert!((offset - 0.5 * gap).abs() > 1e-2 * gap);
    }

    #[test]
    fn contact_is_dead_inside_the_gap_and_only_pushes() {
        let b = carriage_with_play(1e-3).backlash.unwrap();
        assert_eq!(b.contact_force(4e-4, 1.0), 0.0);
        assert_eq!(b.contact_force(-4e-4, -1.0), 0.0);
        assert!(b.contact_force(6e-4, 0.0) > 0.0 && b.contact_force(-6e-4, 0.0) < 0.0);
        // separating fast: the damper may not pull the block back
        assert_eq!(b.contact_force(5.001e-4, -10.0), 0.0);
    }

    #[test]
    fn the_guide_holds_the_block_so_the_play_acts_as_a_dead_band() {
        // up 50 mm, then back 0.5 mm (inside a 1 mm gap), then down to 20 mm: the block (the
        // beam root) trails the motor by half the gap, stays put on the small reversal, and
        // then trails by half the gap from the other side (the play operator of the diagnosis)
        let gap = 1e-3;
        let dt = 1.0 / 4000.0;
        let cmd = moves(&[0.0, 0.05, 0.0495, 0.02], 0.5, 0.5, dt);
        let run = carriage_with_play(gap).run(&cmd, dt);
        let at = |t: f64| {
            let k = (t / dt) as usize;
            (run.y_motor_m[k], run.tip_m[k])
        };
        let (m1, r1) = at(0.99);
        assert!((m1 - r1 - 0.5 * gap).abs() < 0.1 * gap, "{m1} {r1}");
        let (m2, r2) = at(1.99);
        assert!((r2 - r1).abs() < 0.05 * gap, "{r1} {r2} (motor {m2})");
        let (m3, r3) = at(2.99);
        assert!((r3 - m3 - 0.5 * gap).abs() < 0.1 * gap, "{m3} {r3}");
    }
}

//! One Levenberg–Marquardt adapter over the `levenberg-marquardt` crate (MINPACK's algorithm,
//! Moré 1978) for every nonlinear least-squares fit of the tools.
//!
//! The caller gives a residual closure `r(x) -> Option<r>` over a parameter vector `x` (length
//! n, in whatever representation the caller scales it: log, bounded, linear), the
//! finite-difference step of every parameter in that representation, optional box bounds
//! (trial points are projected onto them before evaluation), and an **evaluation budget**: the
//! number of residual evaluations (those of the Jacobian included) after which the closure is no
//! longer called and the minimisation ends. The answer therefore depends only on the inputs,
//! never on the machine or its load. The lowest cost seen is returned (the minimiser may end on
//! a trial point when the budget runs out).
//!
//! **The crate sees the problem compressed to n + 1 rows.** Its trust-region step depends on the
//! residuals only through ‖r‖, JᵀJ and Jᵀr. So the adapter hands it r̃ = (‖r‖, 0, …, 0) and,
//! for the Jacobian, the upper-triangular factor of the thin QR of the m × (n + 1) matrix
//! [r | J] = Q R (R's first row sign-fixed so that R₀₀ = ‖r‖): J̃ = R's last n columns, and
//! then J̃ᵀJ̃ = JᵀJ, J̃ᵀr̃ = Jᵀr and ‖r̃‖ = ‖r‖ exactly in exact arithmetic. It is the same
//! minimisation, step for step, up to rounding. R is accumulated over blocks of
//! [`QR_BLOCK_ROWS`] rows, each block stacked under the R so far and factored by nalgebra's
//! Householder QR (the sequential form of TSQR: Demmel, Grigori, Hoemmen & Langou, SIAM J. Sci.
//! Comput. 34 (2012); MINPACK's `lmstr` accumulates R a row at a time for the same reason:
//! Moré, Garbow & Hillstrom, *User Guide for MINPACK-1*, 1980, §2). A finite-difference
//! Jacobian is never stored whole: each block of its rows is formed from the evaluated points.
//! Why: with 10⁵–10⁶ residuals the crate's pivoted QR of the whole tall Jacobian, the
//! Jacobian's own allocation and its column writes were a quarter of a diagnosis's run time
//! (docs/diagnose.md, "Session 39").
//!
//! At the optimum [`covariance`] gives `(JᵀJ)⁻¹` (eigen-decomposition; a direction the data do
//! not determine gives NaN, "not identified") and [`std_errors`] the linearised 1-σ
//! `sqrt(s² (JᵀJ)⁻¹_ii)` with `s² = cost / (m − n)` (e.g. Seber & Wild 2003, §5.1).

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use std::cell::{Cell, RefCell};

/// Finite-difference scheme of the Jacobian.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Difference {
    /// (r(x + h e_i) − r(x)) / h: n evaluations per Jacobian.
    Forward,
    /// (r(x + h e_i) − r(x − h e_i)) / 2h: 2n evaluations per Jacobian.
    Central,
}

/// Options of one minimisation.
#[derive(Clone, Debug)]
pub struct LmOptions {
    /// Finite-difference step of every parameter (representation units), length n.
    pub steps: Vec<f64>,
    /// Scheme of the finite-difference Jacobian.
    pub difference: Difference,
    /// Optional lower and upper bounds (representation units), each of length n.
    pub bounds: Option<(Vec<f64>, Vec<f64>)>,
    /// Most residual evaluations (Jacobian columns included); `usize::MAX` for none.
    pub max_evaluations: usize,
    /// The crate's patience: at most `patience × (n + 1)` residual evaluations outside the
    /// Jacobian.
    pub patience: usize,
    /// Relative reduction of the cost below which it stops.
    pub ftol: f64,
    /// Relative step below which it stops.
    pub xtol: f64,
    /// Parameters known to have no effect near the start (e.g. a representation clamped by the
    /// model): their Jacobian column is zero without evaluating the closure, as evaluating it
    /// would give. Empty: none.
    pub inert: Vec<bool>,
}

impl LmOptions {
    /// Forward differences with `steps`, the crate's default tolerances (30 ε), patience 100,
    /// no budget.
    pub fn new(steps: Vec<f64>) -> Self {
        LmOptions {
            steps,
            difference: Difference::Forward,
            bounds: None,
            max_evaluations: usize::MAX,
            patience: 100,
            ftol: 30.0 * f64::EPSILON,
            xtol: 30.0 * f64::EPSILON,
            inert: Vec::new(),
        }
    }
}

/// Outcome of one minimisation.
#[derive(Clone, Debug)]
pub struct LmOutcome {
    /// Parameters of the lowest cost seen (projected on the bounds).
    pub x: DVector<f64>,
    /// Σ r² there (∞ if no evaluation succeeded).
    pub cost: f64,
    /// Residual evaluations used (Jacobian columns included).
    pub evaluations: usize,
    /// Why the minimiser stopped, in words (`evaluation budget spent` when the budget ended it).
    pub termination: String,
    /// The crate's termination counts as a success (converged, zero residuals, residuals
    /// orthogonal to the Jacobian); false when the budget ended it.
    pub converged: bool,
    /// Why it stopped in words ([`termination_text`], or `evaluation budget spent`).
    pub reason: String,
}

/// The Levenberg–Marquardt termination in words (no debug text in messages).
pub fn termination_text(t: &levenberg_marquardt::TerminationReason) -> String {
    use levenberg_marquardt::TerminationReason as T;
    match t {
        T::Converged { .. } => "converged".into(),
        T::ResidualsZero => "zero residuals".into(),
        T::Orthogonal => "residuals orthogonal to the Jacobian".into(),
        T::LostPatience => "too many evaluations".into(),
        T::NoImprovementPossible(s) => format!("no improvement possible ({s})"),
        T::NoParameters => "no parameters".into(),
        T::NoResiduals => "no residuals".into(),
        T::WrongDimensions(s) => format!("wrong dimensions ({s})"),
        T::Numerical(s) => format!("numerical problem ({s})"),
        T::User(s) => s.to_string(),
    }
}

/// Projects `x` onto the box `bounds`.
pub fn project(x: &DVector<f64>, bounds: &Option<(Vec<f64>, Vec<f64>)>) -> DVector<f64> {
    match bounds {
        None => x.clone(),
        Some((lo, hi)) => DVector::from_iterator(
            x.len(),
            x.iter().enumerate().map(|(i, v)| v.clamp(lo[i], hi[i])),
        ),
    }
}

/// An analytic Jacobian: x ↦ ∂r/∂x (m × n), `None` where it cannot be evaluated.
pub type JacobianFn<'f> = &'f dyn Fn(&DVector<f64>) -> Option<DMatrix<f64>>;

struct Adapter<'f, F> {
    f: &'f F,
    /// Analytic Jacobian; finite differences of `opts` when `None`.
    jac: Option<JacobianFn<'f>>,
    /// Evaluates a finite-difference Jacobian's points at once when given.
    batch: Option<BatchFn<'f>>,
    opts: &'f LmOptions,
    x: DVector<f64>,
    evaluations: Cell<usize>,
    spent: Cell<bool>,
    /// The whole residual at `x` (the crate asks for the Jacobian right after the residual).
    last: RefCell<Option<(DVector<f64>, DVector<f64>)>>,
    best: RefCell<Option<(f64, DVector<f64>)>>,
}

impl<F: Fn(&DVector<f64>) -> Option<DVector<f64>>> Adapter<'_, F> {
    fn eval(&self, x: &DVector<f64>) -> Option<DVector<f64>> {
        if self.evaluations.get() >= self.opts.max_evaluations {
            self.spent.set(true);
            return None;
        }
        self.evaluations.set(self.evaluations.get() + 1);
        let r = (self.f)(&project(x, &self.opts.bounds))?;
        r.iter().all(|v| v.is_finite()).then_some(r)
    }

    /// Evaluates the residual at `x` unless it is held already; `None` where it cannot be.
    fn evaluate_current(&self) -> Option<()> {
        if let Some((x, _)) = self.last.borrow().as_ref() {
            if *x == self.x {
                return Some(());
            }
        }
        let r = self.eval(&self.x)?;
        let c = r.norm_squared();
        let mut b = self.best.borrow_mut();
        if b.as_ref().map_or(true, |(bc, _)| c < *bc) {
            *b = Some((c, self.x.clone()));
        }
        *self.last.borrow_mut() = Some((self.x.clone(), r));
        Some(())
    }
}

impl<F: Fn(&DVector<f64>) -> Option<DVector<f64>>> LeastSquaresProblem<f64, Dyn, Dyn>
    for Adapter<'_, F>
{
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.x = project(x, &self.opts.bounds);
    }

    fn params(&self) -> DVector<f64> {
        self.x.clone()
    }

    /// r̃ = (‖r‖, 0, …, 0), n + 1 long (module docs); empty for an empty residual.
    fn residuals(&self) -> Option<DVector<f64>> {
        self.evaluate_current()?;
        let last = self.last.borrow();
        let r = &last.as_ref()?.1;
        let rows = compressed_rows(r.len(), self.x.len());
        Some(DVector::from_fn(
            rows,
            |i, _| if i == 0 { r.norm() } else { 0.0 },
        ))
    }

    /// J̃: the last n columns of R in [r | J] = Q R (module docs).
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        self.evaluate_current()?;
        let last = self.last.borrow();
        let r0 = &last.as_ref()?.1;
        let x = self.x.clone();
        if let Some(jac) = self.jac {
            let j = jac(&x)?;
            let m = j.nrows();
            return Some(compressed_jacobian(r0, x.len(), &|c, rows, out| {
                out.copy_from_slice(&j.as_slice()[c * m + rows.start..c * m + rows.end])
            }));
        }
        let points = match self.batch {
            Some(batch) => self.batched_points(batch, &x)?,
            None => fd_points(&|y: &DVector<f64>| self.eval(y), &x, self.opts)?,
        };
        Some(points.compressed(r0, x.len()))
    }
}

impl<F: Fn(&DVector<f64>) -> Option<DVector<f64>>> Adapter<'_, F> {
    /// The finite-difference Jacobian's points evaluated by one call of `batch`, counted as one
    /// after the other would count them; one after the other when the budget ends inside it (so
    /// where it stops is the same).
    fn batched_points(&self, batch: BatchFn<'_>, x: &DVector<f64>) -> Option<FdPoints> {
        let before = self.evaluations.get();
        let needed: usize = fd_columns(x, self.opts)
            .iter()
            .map(|c| c.points.len())
            .sum();
        if before + needed > self.opts.max_evaluations {
            return fd_points(&|y: &DVector<f64>| self.eval(y), x, self.opts);
        }
        let checked = |xs: &[DVector<f64>]| -> Vec<Option<DVector<f64>>> {
            let projected: Vec<DVector<f64>> =
                xs.iter().map(|x| project(x, &self.opts.bounds)).collect();
            batch(&projected)
                .into_iter()
                .map(|r| r.filter(|r| r.iter().all(|v| v.is_finite())))
                .collect()
        };
        match fd_points_batched(&checked, x, self.opts) {
            Ok(p) => {
                self.evaluations.set(before + needed);
                Some(p)
            }
            Err(used) => {
                self.evaluations.set(before + used);
                None
            }
        }
    }
}

/// Rows the crate sees for m residuals and n parameters: n + 1, or none for no residuals.
fn compressed_rows(m: usize, n: usize) -> usize {
    if m == 0 {
        0
    } else {
        n + 1
    }
}

/// Rows per block of the accumulated QR (module docs): a block of [r | J] with up to 16
/// parameters stays within a core's L2 cache (2048 × 17 × 8 B ≈ 280 kB).
pub const QR_BLOCK_ROWS: usize = 2048;

/// J̃ (n + 1 × n) of the module docs for the residual `r0` (m) and a Jacobian given by
/// `fill(c, rows, out)`, which writes the rows `rows` of its column c into `out`. R is
/// accumulated block by block: the R so far stacked over the next [`QR_BLOCK_ROWS`] rows of
/// [r | J], factored by Householder QR. Its first row is negated where R₀₀ < 0, so that
/// R₀₀ = ‖r‖ as r̃ states. Empty (0 × n) for an empty residual.
fn compressed_jacobian(
    r0: &DVector<f64>,
    n: usize,
    fill: &dyn Fn(usize, std::ops::Range<usize>, &mut [f64]),
) -> DMatrix<f64> {
    let (m, k) = (r0.len(), n + 1);
    let mut r = DMatrix::<f64>::zeros(0, k);
    for start in (0..m).step_by(QR_BLOCK_ROWS) {
        let rows = start..(start + QR_BLOCK_ROWS).min(m);
        let top = r.nrows();
        let mut stack = DMatrix::<f64>::zeros(top + rows.len(), k);
        stack.rows_mut(0, top).copy_from(&r);
        let height = stack.nrows();
        for c in 0..k {
            let out = &mut stack.as_mut_slice()[c * height + top..(c + 1) * height];
            if c == 0 {
                out.copy_from_slice(&r0.as_slice()[rows.clone()]);
            } else {
                fill(c - 1, rows.clone(), out);
            }
        }
        r = stack.qr().unpack_r();
    }
    let mut j = DMatrix::<f64>::zeros(compressed_rows(m, n), n);
    let flip = if r.nrows() > 0 && r[(0, 0)] < 0.0 {
        -1.0
    } else {
        1.0
    };
    for i in 0..r.nrows() {
        let sign = if i == 0 { flip } else { 1.0 };
        for c in 0..n {
            j[(i, c)] = sign * r[(i, c + 1)];
        }
    }
    j
}

/// The evaluations one column of a finite-difference Jacobian needs ([`fd_columns`]).
struct FdColumn {
    /// Column of the Jacobian.
    index: usize,
    /// x + h e_i, and for central differences x − h e_i after it.
    points: Vec<DVector<f64>>,
    /// Divisor of the difference: h (forward) or 2h (central).
    step: f64,
}

/// The columns a finite-difference Jacobian at `x` evaluates, in order: every column not marked
/// inert; a step that would leave the bounds is taken the other way.
fn fd_columns(x: &DVector<f64>, opts: &LmOptions) -> Vec<FdColumn> {
    let mut columns = Vec::new();
    for i in 0..x.len() {
        if opts.inert.get(i).copied().unwrap_or(false) {
            continue;
        }
        let mut h = opts.steps[i];
        if let Some((lo, hi)) = &opts.bounds {
            if x[i] + h > hi[i] && x[i] - h >= lo[i] {
                h = -h;
            }
        }
        let mut xp = x.clone();
        xp[i] += h;
        let (points, step) = match opts.difference {
            Difference::Forward => (vec![xp], h),
            Difference::Central => {
                let mut xm = x.clone();
                xm[i] -= h;
                (vec![xp, xm], 2.0 * h)
            }
        };
        columns.push(FdColumn {
            index: i,
            points,
            step,
        });
    }
    columns
}

/// The evaluated points of a finite-difference Jacobian: `values[i]` are the residuals at the
/// points of `columns[i]`, in order.
struct FdPoints {
    columns: Vec<FdColumn>,
    values: Vec<Vec<DVector<f64>>>,
}

impl FdPoints {
    /// The dense m × n Jacobian at a point with residual `r0`: (r₊ − r₀)/h (forward) or
    /// (r₊ − r₋)/2h (central) per evaluated column, zero for the others.
    fn dense(&self, r0: &DVector<f64>, n: usize) -> DMatrix<f64> {
        let m = r0.len();
        let mut j = DMatrix::zeros(m, n);
        for (c, v) in self.columns.iter().zip(&self.values) {
            let out = &mut j.as_mut_slice()[c.index * m..(c.index + 1) * m];
            write_rows(c, v, r0, 0..m, out);
        }
        j
    }

    /// [`compressed_jacobian`] of these points, the Jacobian formed a block of rows at a time.
    fn compressed(&self, r0: &DVector<f64>, n: usize) -> DMatrix<f64> {
        let mut of_parameter = vec![None; n];
        for (i, c) in self.columns.iter().enumerate() {
            of_parameter[c.index] = Some(i);
        }
        compressed_jacobian(r0, n, &|p, rows, out| match of_parameter[p] {
            Some(i) => write_rows(&self.columns[i], &self.values[i], r0, rows, out),
            None => out.fill(0.0),
        })
    }
}

/// Writes the rows `rows` of column `c` of the Jacobian into `out`: (r₊ − r₀)/h (forward) or
/// (r₊ − r₋)/2h (central), from the residuals at the column's points in order.
fn write_rows(
    c: &FdColumn,
    values: &[DVector<f64>],
    r0: &DVector<f64>,
    rows: std::ops::Range<usize>,
    out: &mut [f64],
) {
    let base = values.get(1).unwrap_or(r0);
    let (p, b) = (&values[0].as_slice()[rows.clone()], &base.as_slice()[rows]);
    for ((jk, p), b) in out.iter_mut().zip(p).zip(b) {
        *jk = (p - b) / c.step;
    }
}

/// The points of a finite-difference Jacobian at `x`, evaluated one after the other by `f`;
/// `None` if an evaluation fails (none is made after it).
fn fd_points(
    f: &dyn Fn(&DVector<f64>) -> Option<DVector<f64>>,
    x: &DVector<f64>,
    opts: &LmOptions,
) -> Option<FdPoints> {
    let columns = fd_columns(x, opts);
    let mut values = Vec::with_capacity(columns.len());
    for c in &columns {
        values.push(c.points.iter().map(f).collect::<Option<Vec<_>>>()?);
    }
    Some(FdPoints { columns, values })
}

/// Finite-difference Jacobian of `f` at `x` (residual `r0` there), steps and scheme of `opts`;
/// a step that would leave the bounds is taken the other way; the columns of `opts.inert`
/// parameters are zero, not evaluated. `None` if an evaluation fails (none is made after it).
pub fn fd_jacobian(
    f: &dyn Fn(&DVector<f64>) -> Option<DVector<f64>>,
    x: &DVector<f64>,
    r0: &DVector<f64>,
    opts: &LmOptions,
) -> Option<DMatrix<f64>> {
    Some(fd_points(f, x, opts)?.dense(r0, x.len()))
}

/// Residuals at several points at once, in order (`None` where one cannot be evaluated): the
/// caller may spread them over threads. Its results must be those of the residual closure at
/// the same points.
pub type BatchFn<'f> = &'f dyn Fn(&[DVector<f64>]) -> Vec<Option<DVector<f64>>>;

/// [`fd_points`] with every point evaluated by one call of `batch`. `Err` if an evaluation
/// fails, with the number of evaluations one after the other would have made up to and
/// including the first failure.
fn fd_points_batched(
    batch: BatchFn<'_>,
    x: &DVector<f64>,
    opts: &LmOptions,
) -> Result<FdPoints, usize> {
    let columns = fd_columns(x, opts);
    let points: Vec<DVector<f64>> = columns.iter().flat_map(|c| c.points.clone()).collect();
    let mut results = batch(&points).into_iter();
    let mut values = Vec::with_capacity(columns.len());
    let mut used: usize = 0;
    for c in &columns {
        let mut v = Vec::with_capacity(c.points.len());
        for _ in &c.points {
            used += 1;
            v.push(results.next().flatten().ok_or(used)?);
        }
        values.push(v);
    }
    Ok(FdPoints { columns, values })
}

/// [`fd_jacobian`] with every point evaluated by one call of `batch` (which may spread them over
/// threads): the same Jacobian. `None` if an evaluation fails, with the number of evaluations
/// one after the other would have made up to and including the first failure.
pub fn fd_jacobian_batched(
    batch: BatchFn<'_>,
    x: &DVector<f64>,
    r0: &DVector<f64>,
    opts: &LmOptions,
) -> Result<DMatrix<f64>, usize> {
    Ok(fd_points_batched(batch, x, opts)?.dense(r0, x.len()))
}

/// Minimises Σ r(x)² from `x0` (module docs). The closure is called with parameters projected
/// on the bounds; it returns `None` where the model refuses them (the minimiser then shortens
/// its step).
pub fn minimize<F>(f: &F, x0: DVector<f64>, opts: &LmOptions) -> LmOutcome
where
    F: Fn(&DVector<f64>) -> Option<DVector<f64>>,
{
    minimize_inner(f, None, None, x0, opts)
}

/// [`minimize`] whose finite-difference Jacobians evaluate their points with one call of
/// `batch` (e.g. spread over threads). `batch` must give what `f` gives at the same points; the
/// minimisation, its evaluation count and its result are then those of [`minimize`].
pub fn minimize_batched<F>(
    f: &F,
    batch: BatchFn<'_>,
    x0: DVector<f64>,
    opts: &LmOptions,
) -> LmOutcome
where
    F: Fn(&DVector<f64>) -> Option<DVector<f64>>,
{
    minimize_inner(f, None, Some(batch), x0, opts)
}

/// [`minimize`] with an analytic Jacobian `jac` instead of finite differences (`opts.steps` and
/// `opts.difference` are then unused; Jacobian evaluations do not count against the budget).
pub fn minimize_with_jacobian<F>(
    f: &F,
    jac: JacobianFn<'_>,
    x0: DVector<f64>,
    opts: &LmOptions,
) -> LmOutcome
where
    F: Fn(&DVector<f64>) -> Option<DVector<f64>>,
{
    minimize_inner(f, Some(jac), None, x0, opts)
}

fn minimize_inner<F>(
    f: &F,
    jac: Option<JacobianFn<'_>>,
    batch: Option<BatchFn<'_>>,
    x0: DVector<f64>,
    opts: &LmOptions,
) -> LmOutcome
where
    F: Fn(&DVector<f64>) -> Option<DVector<f64>>,
{
    let x0 = project(&x0, &opts.bounds);
    let adapter = Adapter {
        f,
        jac,
        batch,
        opts,
        x: x0.clone(),
        evaluations: Cell::new(0),
        spent: Cell::new(false),
        last: RefCell::new(None),
        best: RefCell::new(None),
    };
    let (adapter, report) = LevenbergMarquardt::new()
        .with_patience(opts.patience)
        .with_ftol(opts.ftol)
        .with_xtol(opts.xtol)
        .minimize(adapter);
    let spent = "evaluation budget spent".to_string();
    let (termination, reason, converged) = if adapter.spent.get() {
        (spent.clone(), spent, false)
    } else {
        (
            format!("{:?}", report.termination),
            termination_text(&report.termination),
            report.termination.was_successful(),
        )
    };
    let (cost, x) = adapter.best.borrow().clone().unwrap_or((f64::INFINITY, x0));
    LmOutcome {
        x,
        cost,
        evaluations: adapter.evaluations.get(),
        termination,
        converged,
        reason,
    }
}

/// (JᵀJ)⁻¹ by eigen-decomposition; a parameter with weight in a direction the data do not
/// determine (eigenvalue below 1e-10 of the largest) gets NaN variance ("not identified")
/// rather than a meaningless tiny number.
///
/// The columns are scaled to unit norm first (Jacobi preconditioning, undone afterwards), so
/// that "not identified" is judged on correlation, not on the units of a parameter (a cubic
/// stiffness in N·m/rad³ has a column 10⁻¹⁰ the size of a log-scale one).
pub fn covariance(j: &DMatrix<f64>) -> DMatrix<f64> {
    let n = j.ncols();
    if n == 0 || j.nrows() == 0 {
        // nothing to estimate (or no data): every parameter is "not identified"
        return DMatrix::from_element(n, n, f64::NAN);
    }
    // a column of zeros (a parameter without effect) keeps scale 1 and is reported NaN below
    let norms: Vec<f64> = (0..n)
        .map(|i| j.column(i).norm())
        .map(|v| if v > 0.0 && v.is_finite() { v } else { 1.0 })
        .collect();
    let mut js = j.clone();
    for (i, s) in norms.iter().enumerate() {
        js.column_mut(i).unscale_mut(*s);
    }
    let mut cov = scaled_covariance(&js);
    for r in 0..n {
        for c in 0..n {
            cov[(r, c)] /= norms[r] * norms[c];
        }
    }
    cov
}

/// [`covariance`] of a column-normalised Jacobian.
fn scaled_covariance(j: &DMatrix<f64>) -> DMatrix<f64> {
    let (mut cov, unidentified) = scaled_pseudo_inverse(j);
    for i in 0..cov.nrows() {
        if unidentified[i] {
            cov[(i, i)] = f64::NAN;
        }
    }
    cov
}

/// Pseudo-inverse of JᵀJ of a column-normalised Jacobian (eigenvalues below 1e-10 of the
/// largest dropped) and, per parameter, whether it has weight (> 1e-3) in a dropped direction.
fn scaled_pseudo_inverse(j: &DMatrix<f64>) -> (DMatrix<f64>, Vec<bool>) {
    let n = j.ncols();
    let jtj = j.transpose() * j;
    if !jtj.iter().all(|v| v.is_finite()) {
        return (DMatrix::from_element(n, n, f64::NAN), vec![true; n]);
    }
    let eig = nalgebra::SymmetricEigen::new(jtj);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut cov = DMatrix::zeros(n, n);
    let mut null_weight = vec![0.0; n];
    for k in 0..n {
        let l = eig.eigenvalues[k];
        let v = eig.eigenvectors.column(k);
        if l > 1e-10 * lmax && l > 0.0 {
            cov += v * v.transpose() / l;
        } else {
            for i in 0..n {
                null_weight[i] += v[i] * v[i];
            }
        }
    }
    (cov, null_weight.iter().map(|w| *w > 1e-3).collect())
}

/// Linearised 1-σ of every parameter (representation units) from the Jacobian `j` of the
/// residuals at the optimum and the cost Σ r² there: sqrt(s² (JᵀJ)⁻¹_ii), s² = cost/(m − n)
/// (m residuals, n parameters); NaN where not identified.
pub fn std_errors(j: &DMatrix<f64>, cost: f64) -> Vec<f64> {
    let (m, n) = (j.nrows() as f64, j.ncols());
    let s2 = cost / (m - n as f64).max(1.0);
    let cov = covariance(j);
    // NaN stays NaN (`f64::max` would turn it into 0, a confident "± 0")
    (0..n)
        .map(|i| {
            let v = s2 * cov[(i, i)];
            if v.is_nan() {
                f64::NAN
            } else {
                v.max(0.0).sqrt()
            }
        })
        .collect()
}

/// Linearised 1-σ of every parameter (representation units) when the residuals are *not*
/// independent: the sandwich (Huber–White) covariance `(JᵀJ)⁻¹ S (JᵀJ)⁻¹` with the long-run
/// covariance of the scores g_t = J_tᵀ r_t estimated by non-overlapping batch means
/// (S = Σ_blocks G_b G_bᵀ, G_b = Σ_{t∈b} g_t; e.g. Flegal & Jones 2010) inside each of the
/// independent `segments` (lengths of the consecutive series r is made of: one per recording and
/// channel; their sum must be `r.len()`, else r is one series). The block length is
/// `block_factor` × the largest integrated autocorrelation time ([`crate::numeric::stats::autocorrelation_time`],
/// at most `max_lag` lags) of a score, capped at a tenth of the segment. For white residuals it
/// equals [`std_errors`] in expectation; for a residual correlated over τ samples it is about
/// √τ larger, which `s² (JᵀJ)⁻¹` misses. NaN where not identified (as [`covariance`]).
///
/// `j`: m × n, `r`: m, `segments`: lengths summing to m.
pub fn std_errors_long_run(
    j: &DMatrix<f64>,
    r: &DVector<f64>,
    segments: &[usize],
    max_lag: usize,
    block_factor: f64,
) -> Vec<f64> {
    let (m, n) = (j.nrows(), j.ncols());
    if n == 0 || m == 0 || r.len() != m {
        return vec![f64::NAN; n];
    }
    let whole = [m];
    let segs: &[usize] = if segments.iter().sum::<usize>() == m {
        segments
    } else {
        &whole
    };
    let norms: Vec<f64> = (0..n)
        .map(|i| j.column(i).norm())
        .map(|v| if v > 0.0 && v.is_finite() { v } else { 1.0 })
        .collect();
    let mut js = j.clone();
    for (i, s) in norms.iter().enumerate() {
        js.column_mut(i).unscale_mut(*s);
    }
    let (pinv, unidentified) = scaled_pseudo_inverse(&js);
    // scores of the normalised parameters
    let scores: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            js.column(i)
                .iter()
                .zip(r.iter())
                .map(|(a, b)| a * b)
                .collect()
        })
        .collect();
    let mut s_mat = DMatrix::<f64>::zeros(n, n);
    let mut start = 0;
    for &len in segs {
        let end = start + len;
        if len == 0 {
            continue;
        }
        let tau = scores
            .iter()
            .map(|g| crate::numeric::stats::autocorrelation_time(&g[start..end], max_lag))
            .fold(1.0, f64::max);
        let block = ((block_factor * tau).ceil() as usize).clamp(1, (len / 10).max(1));
        let mut b0 = start;
        while b0 < end {
            let b1 = (b0 + block).min(end);
            let g = DVector::from_iterator(n, scores.iter().map(|s| s[b0..b1].iter().sum::<f64>()));
            s_mat += &g * g.transpose();
            b0 = b1;
        }
        start = end;
    }
    let cov = &pinv * s_mat * &pinv;
    (0..n)
        .map(|i| {
            let v = cov[(i, i)];
            if unidentified[i] || !v.is_finite() {
                f64::NAN
            } else {
                v.max(0.0).sqrt() / norms[i]
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// y = a exp(−b t) + noise-free: recovers (a, b) and counts evaluations.
    #[test]
    fn fits_an_exponential_and_respects_the_budget() {
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let f = |x: &DVector<f64>| {
            Some(DVector::from_iterator(
                t.len(),
                t.iter().zip(&y).map(|(t, y)| x[0] * (-x[1] * t).exp() - y),
            ))
        };
        let opts = LmOptions::new(vec![1e-6, 1e-6]);
        let out = minimize(&f, DVector::from_vec(vec![1.0, 0.2]), &opts);
        assert!(
            (out.x[0] - 2.0).abs() < 1e-6 && (out.x[1] - 0.7).abs() < 1e-6,
            "{out:?}"
        );
        assert!(out.cost < 1e-12);
        let budget = LmOptions {
            max_evaluations: 7,
            ..opts.clone()
        };
        let short = minimize(&f, DVector::from_vec(vec![1.0, 0.2]), &budget);
        assert_eq!(short.evaluations, 7);
        assert_eq!(short.termination, "evaluation budget spent");
        // deterministic: the same budget gives the same point
        let again = minimize(&f, DVector::from_vec(vec![1.0, 0.2]), &budget);
        assert_eq!(short.x, again.x);
        assert!(
            short.cost
                < f(&DVector::from_vec(vec![1.0, 0.2]))
                    .unwrap()
                    .norm_squared()
        );
    }

    #[test]
    fn an_inert_parameter_costs_no_evaluation_and_ends_where_it_began() {
        // x[1] is clamped by the model beyond 1 (no effect there): the fit of x[0] is the same
        // with it marked inert, for one evaluation fewer per Jacobian
        let calls = Cell::new(0usize);
        let f = |x: &DVector<f64>| {
            calls.set(calls.get() + 1);
            let c = x[1].min(1.0);
            Some(DVector::from_vec(vec![x[0] - 3.0 * c, 0.1 * (x[0] - 2.0)]))
        };
        let x0 = DVector::from_vec(vec![0.0, 5.0]);
        let plain = minimize(&f, x0.clone(), &LmOptions::new(vec![1e-6, 1e-6]));
        let plain_calls = calls.replace(0);
        let opts = LmOptions {
            inert: vec![false, true],
            ..LmOptions::new(vec![1e-6, 1e-6])
        };
        let inert = minimize(&f, x0, &opts);
        assert!(
            (inert.x[0] - plain.x[0]).abs() < 1e-9,
            "{inert:?} {plain:?}"
        );
        assert_eq!(inert.x[1], 5.0);
        assert!(
            calls.get() < plain_calls,
            "{} vs {plain_calls}",
            calls.get()
        );
        let r0 = f(&plain.x).unwrap();
        let j = fd_jacobian(&f, &plain.x, &r0, &opts).unwrap();
        assert_eq!(j.column(1).norm(), 0.0);
    }

    #[test]
    fn a_batched_jacobian_gives_the_same_minimisation_to_the_bit() {
        // exp(−k t) + c, 3 parameters, bounded; the batch evaluates its points on two threads,
        // the second half first, and must change nothing: not the path, not the count, not
        // where a budget that ends inside a Jacobian stops
        let t: Vec<f64> = (0..40).map(|i| 0.1 * i as f64).collect();
        let y: Vec<f64> = t.iter().map(|t| 1.7 * (-0.8 * t).exp() + 0.3).collect();
        let f = |x: &DVector<f64>| {
            Some(DVector::from_iterator(
                t.len(),
                t.iter()
                    .zip(&y)
                    .map(|(t, y)| x[0] * (-x[1] * t).exp() + x[2] - y),
            ))
        };
        let batch = |xs: &[DVector<f64>]| -> Vec<Option<DVector<f64>>> {
            let (a, b) = xs.split_at(xs.len() / 2);
            std::thread::scope(|s| {
                let later = s.spawn(|| b.iter().map(f).collect::<Vec<_>>());
                let mut out: Vec<_> = a.iter().map(f).collect();
                out.extend(later.join().unwrap());
                out
            })
        };
        let x0 = DVector::from_vec(vec![1.0, 0.3, 0.0]);
        for difference in [Difference::Forward, Difference::Central] {
            for max_evaluations in [usize::MAX, 23, 24, 25] {
                let opts = LmOptions {
                    difference,
                    max_evaluations,
                    bounds: Some((vec![0.0, 0.0, -1.0], vec![5.0, 0.81, 1.0])),
                    ..LmOptions::new(vec![1e-6; 3])
                };
                let plain = minimize(&f, x0.clone(), &opts);
                let batched = minimize_batched(&f, &batch, x0.clone(), &opts);
                let bits = |v: &DVector<f64>| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(
                    bits(&plain.x),
                    bits(&batched.x),
                    "{difference:?} {max_evaluations}"
                );
                assert_eq!(plain.cost.to_bits(), batched.cost.to_bits());
                assert_eq!(plain.evaluations, batched.evaluations);
                assert_eq!(plain.termination, batched.termination);
            }
        }
        // a point that cannot be evaluated counts as one after the other would count it
        let refuse_second = |xs: &[DVector<f64>]| -> Vec<Option<DVector<f64>>> {
            xs.iter()
                .enumerate()
                .map(|(i, x)| (i != 1).then(|| f(x).unwrap()))
                .collect()
        };
        let r0 = f(&x0).unwrap();
        let opts = LmOptions::new(vec![1e-6; 3]);
        assert_eq!(fd_jacobian_batched(&refuse_second, &x0, &r0, &opts), Err(2));
        let j = fd_jacobian(&f, &x0, &r0, &opts).unwrap();
        assert_eq!(fd_jacobian_batched(&batch, &x0, &r0, &opts), Ok(j));
    }

    /// The crate's view (module docs): J̃ᵀJ̃ = JᵀJ and J̃ᵀr̃ = Jᵀr with r̃ = (‖r‖, 0, …), over
    /// several blocks of rows, with a zero column and whatever the sign of R₀₀.
    #[test]
    fn the_compressed_jacobian_keeps_the_normal_equations() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        for (m, scale) in [
            (2 * QR_BLOCK_ROWS + 37, 1.0),
            (5, -1.0),
            (QR_BLOCK_ROWS, 1e-6),
        ] {
            let r = DVector::from_fn(m, |_, _| scale * rng.gen_range(-1.0..1.0));
            let mut j = DMatrix::from_fn(m, 4, |i, c| (i as f64 * 0.01 * (c + 1) as f64).sin());
            j.column_mut(2).fill(0.0);
            j.column_mut(3).add_scalar_mut(rng.gen_range(-1.0..1.0));
            let jt = compressed_jacobian(&r, 4, &|c, rows, out| {
                out.copy_from_slice(&j.as_slice()[c * m + rows.start..c * m + rows.end])
            });
            assert_eq!(jt.shape(), (5, 4));
            let rt = DVector::from_fn(5, |i, _| if i == 0 { r.norm() } else { 0.0 });
            let (g, gt) = (j.transpose() * &j, jt.transpose() * &jt);
            let (b, bt) = (j.transpose() * &r, jt.transpose() * &rt);
            assert!((&g - &gt).amax() <= 1e-12 * g.amax(), "{m}: {g} {gt}");
            assert!(
                (&b - &bt).amax() <= 1e-12 * b.amax().max(1e-300),
                "{m}: {b} {bt}"
            );
            assert_eq!(jt.column(2).amax(), 0.0);
        }
        assert_eq!(
            compressed_jacobian(&DVector::zeros(0), 3, &|_, _, _| ()).shape(),
            (0, 3)
        );
    }

    /// A linear least-squares problem of 10⁴ residuals (five blocks): the minimiser lands on the
    /// solution of the normal equations.
    #[test]
    fn a_tall_linear_problem_reaches_its_least_squares_solution() {
        let m = 10_000;
        let a = DMatrix::from_fn(m, 3, |i, c| ((i * (c + 2)) as f64 * 1e-3).cos() + c as f64);
        let y = DVector::from_fn(m, |i, _| (i as f64 * 7e-4).sin());
        let f = |x: &DVector<f64>| Some(&a * x - &y);
        let out = minimize(&f, DVector::zeros(3), &LmOptions::new(vec![1e-6; 3]));
        let exact = (a.transpose() * &a)
            .cholesky()
            .unwrap()
            .solve(&(a.transpose() * &y));
        assert!((&out.x - &exact).amax() < 1e-6, "{} vs {exact}", out.x);
        let best = (&a * &exact - &y).norm_squared();
        assert!(
            (out.cost - best).abs() <= 1e-9 * best,
            "{} vs {best}",
            out.cost
        );
    }

    #[test]
    fn bounds_are_respected() {
        // minimum of (x − 3)² at 3, bounded above by 1
        let f = |x: &DVector<f64>| Some(DVector::from_vec(vec![x[0] - 3.0]));
        let opts = LmOptions {
            bounds: Some((vec![-1.0], vec![1.0])),
            ..LmOptions::new(vec![1e-6])
        };
        let out = minimize(&f, DVector::from_vec(vec![0.0]), &opts);
        assert!((out.x[0] - 1.0).abs() < 1e-9, "{out:?}");
    }

    #[test]
    fn standard_errors_of_a_mean() {
        // r_i = x − y_i: the 1-σ of the mean is s/√m
        let y = [1.0, 2.0, 3.0, 4.0];
        let j = DMatrix::from_element(4, 1, 1.0);
        let cost: f64 = y.iter().map(|v| (v - 2.5f64).powi(2)).sum();
        let s = std_errors(&j, cost)[0];
        let expect = (cost / 3.0 / 4.0).sqrt();
        assert!((s - expect).abs() < 1e-12);
        // an undetermined direction is NaN
        let j2 = DMatrix::from_row_slice(2, 2, &[1.0, 1.0, 1.0, 1.0]);
        assert!(std_errors(&j2, 1.0).iter().all(|v| v.is_nan()));
    }

    /// The mean of an AR(1) series with φ = 0.9: the naive σ is too small by √τ ≈ √19; the
    /// long-run σ matches the scatter of the mean over many series; for white noise the two
    /// agree.
    #[test]
    fn long_run_errors_match_the_scatter_of_a_correlated_mean() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let noise = Normal::new(0.0, 1.0).unwrap();
        let m = 4000;
        let (mut means, mut naive, mut long) = (vec![], vec![], vec![]);
        for phi in [0.9, 0.0] {
            for _ in 0..60 {
                let mut y = vec![0.0; m];
                let mut prev = 0.0;
                for v in y.iter_mut() {
                    prev = phi * prev + noise.sample(&mut rng);
                    *v = prev;
                }
                let mean = y.iter().sum::<f64>() / m as f64;
                let r = DVector::from_iterator(m, y.iter().map(|v| mean - v));
                let j = DMatrix::from_element(m, 1, 1.0);
                means.push(mean);
                naive.push(std_errors(&j, r.norm_squared())[0]);
                long.push(std_errors_long_run(&j, &r, &[m], 2000, 5.0)[0]);
            }
            let scatter = (means.iter().map(|v| v * v).sum::<f64>() / means.len() as f64).sqrt();
            let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let (sn, sl) = (avg(&naive), avg(&long));
            assert!(
                (sl / scatter - 1.0).abs() < 0.3,
                "φ {phi}: long-run {sl} vs scatter {scatter}"
            );
            if phi > 0.0 {
                assert!(sn < 0.4 * scatter, "naive {sn} vs scatter {scatter}");
            } else {
                assert!((sn / scatter - 1.0).abs() < 0.3);
            }
            means.clear();
            naive.clear();
            long.clear();
        }
    }
}

//! MPC with a built-in Kalman filter (section 3.3, eqs 30-35), the QP solved by Clarabel.
//!
//! Model: the vehicle discretised at the MPC period T (eq 30) augmented with an integrated
//! output disturbance d, `ξ = Ψ x + d` (10 states, as the printed L_est has 10 entries).
//! Estimator: steady-state Kalman filter from the discrete Riccati equation (process noise
//! Γ W_n Γᵀ by Van Loan, `disturbance_var` on d, measurement V_n per sample).
//!
//! QP (eq 34) over `[Δu_0 … Δu_{M−1}, ε]`, with the prediction `Ξ = f + Θ Δu`:
//! `min Σ_i λ_ξ (ξ_{k+i} − r_{k+i})² + Σ_j λ_Δu Δu_j² + λ_ε ε²` subject to
//! hard `|u| ≤ u_max`, `|Δu| ≤ Δu_max` and soft `|ξ| ≤ ξ_max + ε`, `ε ≥ 0`
//! (model-notes: hard inputs, soft output). The reference over the horizon is the current one
//! held (the paper's MPC) or, with `preview`, the track database's future reference.
//!
//! Clarabel is an interior-point solver and takes no primal warm start; what it allows is
//! keeping one solver and updating `q` and `b` in place (`update_q`, `update_b`), which skips
//! the set-up and the symbolic factorisation. That is done every period. The solver's
//! settings are fitted to this QP:
//! * Iterative refinement of the KKT solves is off: on this 3-variable QP it costs a third of
//!   the update and moves the solution by less than the solver's tolerance.
//! * Ruiz equilibration is off and the gap and feasibility tolerances are 1e-10 instead of
//!   1e-8 ([`QP_TOLERANCE`]). The QP is small and already well scaled (radians, weights of
//!   order one); unequilibrated, the interior-point method takes 9-13 iterations to 1e-10.
//! * Measured against the closed-form optimum Δu* = −H⁻¹g on the 12 165 updates of the
//!   benchmark where no constraint is active: |Δu₀ − Δu₀*| p50 3.5e-9 rad, max 4.8e-6 rad
//!   (an inactive constraint with little slack still pulls an interior-point iterate; test
//!   `mpc_meets_its_closed_form_in_closed_loop`).
//! * Rows that cannot bind are left out ([`Mpc::rows_needed`], [`QpRows`]): three solvers are
//!   set up once, the full QP, the QP without the soft output rows and the slack, and the QP
//!   of the move limits only, and each update solves the smallest whose optimum is the full
//!   QP's. With the paper's 6° output limit the output rows never bind on its track; an
//!   update takes about half the time of the full QP.
//!
//! Figures: `cargo bench -p controller-proc --bench mpc`; each setting's measured effect is in
//! docs/performance.md, "The MPC update". A solve that does not end
//! `Solved`/`AlmostSolved` is counted and the previous command is held (Δu = 0, always
//! feasible).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::design::LinearModel;
use crate::linalg::{dare, van_loan, DesignError};
use crate::lqg::{process_noise, KalmanSettings};
use tiltsim_protocol::settings::Checker;

/// Clarabel's duality-gap and feasibility tolerances (its default is 1e-8; module notes).
const QP_TOLERANCE: f64 = 1e-10;

/// MPC settings (scenario `[controller.mpc]`); the period is `controller.period_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MpcSettings {
    /// Prediction horizon p (steps).
    pub horizon_p: usize,
    /// Control horizon M (moves).
    pub horizon_m: usize,
    /// Output weight λ_ξ (on rad²).
    pub output_weight: f64,
    /// Input-rate weight λ_Δu (on rad²).
    pub rate_weight: f64,
    /// Largest move |Δu| per period (deg).
    pub du_max_deg: f64,
    /// Soft output limit |θ_v| (deg).
    pub theta_v_max_deg: f64,
    /// Weight λ_ε on the squared slack (rad²) of the soft output limit.
    pub slack_weight: f64,
    /// Feed the future reference from the track database over the horizon (ours, not the
    /// paper's).
    pub preview: bool,
    /// Clarabel's iteration limit.
    pub max_iter: u32,
}

impl Default for MpcSettings {
    fn default() -> Self {
        MpcSettings {
            horizon_p: 5,
            horizon_m: 2,
            output_weight: 3.60,
            rate_weight: 0.028,
            du_max_deg: 0.5,
            theta_v_max_deg: 6.0,
            slack_weight: 1e5,
            preview: false,
            max_iter: 50,
        }
    }
}

impl MpcSettings {
    /// Checks every field.
    pub fn validate(&self, c: &mut Checker) {
        c.range("mpc.horizon_p", self.horizon_p as f64, 1.0, 200.0, "steps");
        c.range(
            "mpc.horizon_m",
            self.horizon_m as f64,
            1.0,
            self.horizon_p.max(1) as f64,
            "moves (at most horizon_p)",
        );
        c.positive("mpc.output_weight", self.output_weight, 1e9, "");
        c.positive("mpc.rate_weight", self.rate_weight, 1e9, "");
        c.positive("mpc.du_max_deg", self.du_max_deg, 90.0, "deg");
        c.positive("mpc.theta_v_max_deg", self.theta_v_max_deg, 90.0, "deg");
        c.positive("mpc.slack_weight", self.slack_weight, 1e12, "");
        c.range("mpc.max_iter", self.max_iter as f64, 5.0, 1000.0, "");
    }
}

/// How the command is applied over each MPC period, as the prediction model assumes it
/// (it must match the actuator's `command_shaping`; the engine derives it from there).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum InputShape {
    /// Zero-order hold: u(t) = u_k over [t_k, t_k + T) (the paper's eq 30).
    #[default]
    Hold,
    /// Linear ramp from u_{k−1} to u_k over the period, then held:
    /// x_{k+1} = Φ x_k + Γ u_{k−1} + Γ₁ Δu_k with Γ₁ = ∫₀ᵀ e^{A(T−τ)} B τ/T dτ.
    Ramp,
}

/// The inputs of one MPC update.
#[derive(Debug, Clone)]
pub struct MpcInput<'a> {
    /// Measured θ_v (rad).
    pub xi: f64,
    /// References r(k+1) … r(k+p) (rad).
    pub r: &'a [f64],
    /// Known track input ω(k) … ω(k+p−1) (zeros when the estimator does not use it).
    pub w: &'a [[f64; 6]],
}

/// One MPC update's outcome.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpcUpdate {
    /// Command u(k) (rad).
    pub u: f64,
    /// Filtered roll estimate ξ̂(k|k) = θ̂_v + d̂ (rad): the model's roll plus the estimated
    /// output disturbance.
    pub theta_v_hat: f64,
    /// Clarabel iterations.
    pub iterations: u32,
    /// Whether the QP was solved (otherwise the previous command was held).
    pub solved: bool,
}

/// The running MPC-KF.
pub struct Mpc {
    s: MpcSettings,
    u_max: f64,
    du_max: f64,
    y_max: f64,
    /// Augmented discrete model (10 states).
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    /// Response to a unit move ramped over the period (Γ₁; equal to `b` for a hold).
    b1: DMatrix<f64>,
    /// The input shape the prediction assumes.
    pub input_shape: InputShape,
    g: DMatrix<f64>,
    c: DMatrix<f64>,
    /// Kalman gain L_est (10×1), current-estimate form.
    pub l_est: DMatrix<f64>,
    /// Prediction: rows C Aⁱ (p×10), i = 1..p.
    fx: DMatrix<f64>,
    /// Step-response sums S_i = Σ_{j<i} C Aʲ B (p).
    step: Vec<f64>,
    /// Disturbance responses C A^{i−1−j} Γ (p×p blocks of 1×6).
    fw: Vec<Vec<[f64; 6]>>,
    /// Θ (p×M).
    pub theta: DMatrix<f64>,
    /// The furthest the moves can shift each predicted output, Σ_l |Θ_il| Δu_max (rad, p).
    reach: Vec<f64>,
    /// Hessian without the slack, Θᵀ Λ_ξ Θ + Λ_Δu (M×M).
    pub h: DMatrix<f64>,
    /// The QP (eq 34) in each of its forms, indexed by [`QpRows`]: every form is set up once.
    forms: [QpForm; 3],
    x_hat: DMatrix<f64>,
    u_prev: f64,
    q: Vec<f64>,
    bvec: Vec<f64>,
    track_input: bool,
    /// The update's working space, sized once: an update allocates nothing.
    work: Work,
}

/// The buffers of one update ([`Mpc::step`]). Each product is written with `mul_to`, the
/// kernel `*` itself calls, so the values are those of the expressions they replace, bit for
/// bit.
struct Work {
    /// Filtered state x̂(k|k) (10×1).
    x_f: DMatrix<f64>,
    /// The predicted state x̂(k+1|k) (10×1).
    next: DMatrix<f64>,
    /// Γ ω (10×1).
    gw: DMatrix<f64>,
    /// ω (6×1).
    w: DMatrix<f64>,
    /// A 1×1 product (C x, a row of the prediction times x).
    one: DMatrix<f64>,
    /// The free response f (p).
    f: Vec<f64>,
}

impl Work {
    fn new(n: usize, p: usize) -> Self {
        Work {
            x_f: DMatrix::zeros(n, 1),
            next: DMatrix::zeros(n, 1),
            gw: DMatrix::zeros(n, 1),
            w: DMatrix::zeros(6, 1),
            one: DMatrix::zeros(1, 1),
            f: Vec::with_capacity(p),
        }
    }
}

/// Which rows of the QP (eq 34) an update solves. Rows are left out only where they cannot
/// bind whatever moves the other rows allow, so every form has the full QP's optimum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QpRows {
    /// Every row, and the slack ε.
    Full,
    /// The input rows (|u| ≤ u_max, |Δu| ≤ Δu_max), no slack: no soft output row can bind.
    Inputs,
    /// The move rows |Δu| ≤ Δu_max only: neither an output row nor an input-level row can bind.
    Moves,
}

/// One form of the QP: its Clarabel solver, the rows of the full QP it keeps and its
/// variables (the first `nv` of `[Δu; ε]`), with its own `q` and `b` to update in place.
struct QpForm {
    solver: DefaultSolver<f64>,
    rows: std::ops::Range<usize>,
    q: Vec<f64>,
    b: Vec<f64>,
}

fn dense_to_csc(m: &DMatrix<f64>, upper_only: bool) -> CscMatrix<f64> {
    let (mut colptr, mut rowval, mut nzval) = (vec![0], Vec::new(), Vec::new());
    for j in 0..m.ncols() {
        for i in 0..m.nrows() {
            if (upper_only && i > j) || m[(i, j)] == 0.0 {
                continue;
            }
            rowval.push(i);
            nzval.push(m[(i, j)]);
        }
        colptr.push(rowval.len());
    }
    CscMatrix::new(m.nrows(), m.ncols(), colptr, rowval, nzval)
}

/// The model discretised over the controller period and augmented with the output
/// disturbance (state 10): x⁺ = A x + B u (Γ₁ the input's effect under `input_shape` over one
/// period), w through G, y = C x.
struct Augmented {
    a: DMatrix<f64>,
    b: DMatrix<f64>,
    b1: DMatrix<f64>,
    g: DMatrix<f64>,
    c: DMatrix<f64>,
}

fn augmented(m: &LinearModel, period: f64, input_shape: InputShape) -> Augmented {
    let d = m.discretise(period);
    let n = 10;
    let mut a = DMatrix::identity(n, n);
    a.view_mut((0, 0), (9, 9)).copy_from(&d.a);
    let mut b = DMatrix::zeros(n, 1);
    b.view_mut((0, 0), (9, 1)).copy_from(&d.b);
    let b1 = match input_shape {
        InputShape::Hold => b.clone(),
        InputShape::Ramp => {
            // The ramp as the state of an integrator driven by 1/T: [ẋ; u̇] =
            // [A B; 0 0][x; u] + [0; 1/T]·1, discretised exactly over T from u = 0.
            let mut aa = DMatrix::zeros(10, 10);
            aa.view_mut((0, 0), (9, 9)).copy_from(&m.a);
            aa.view_mut((0, 9), (9, 1)).copy_from(&m.b);
            let mut bb = DMatrix::zeros(10, 1);
            bb[(9, 0)] = 1.0 / period;
            let (_, g1) = crate::linalg::c2d(&aa, &bb, period);
            let mut b1 = DMatrix::zeros(n, 1);
            b1.view_mut((0, 0), (9, 1))
                .copy_from(&g1.view((0, 0), (9, 1)));
            b1
        }
    };
    let mut g = DMatrix::zeros(n, 6);
    g.view_mut((0, 0), (9, 6)).copy_from(&d.g);
    let mut c = DMatrix::zeros(1, n);
    c.view_mut((0, 0), (1, 9)).copy_from(&d.c);
    c[(0, 9)] = 1.0;
    Augmented { a, b, b1, g, c }
}

/// The Kalman filter's gain from the dual DARE of the augmented model.
fn kalman_gain(
    m: &LinearModel,
    k: &KalmanSettings,
    a: &DMatrix<f64>,
    c: &DMatrix<f64>,
    period: f64,
) -> Result<DMatrix<f64>, DesignError> {
    let n = 10;
    let mut qn = DMatrix::zeros(n, n);
    qn.view_mut((0, 0), (9, 9))
        .copy_from(&van_loan(&m.a, &process_noise(m, &k.w_n), period));
    qn[(9, 9)] = k.disturbance_var;
    let rn = DMatrix::from_element(1, 1, k.v_n);
    let pk = dare(&a.transpose(), &c.transpose(), &qn, &rn)?;
    let sgain = (c * &pk * c.transpose())[(0, 0)] + k.v_n;
    Ok(&pk * c.transpose() / sgain)
}

/// The prediction over `p` periods: the free response's state map F_x, the step response S,
/// the preview's map of w, and Θ, the outputs' response to the `mm` moves.
struct Prediction {
    fx: DMatrix<f64>,
    step: Vec<f64>,
    fw: Vec<Vec<[f64; 6]>>,
    theta: DMatrix<f64>,
}

fn prediction(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    b1: &DMatrix<f64>,
    g: &DMatrix<f64>,
    c: &DMatrix<f64>,
    p: usize,
    mm: usize,
) -> Prediction {
    let n = a.nrows();
    let mut powers = vec![DMatrix::identity(n, n)];
    for i in 1..=p {
        let next = a * &powers[i - 1];
        powers.push(next);
    }
    let mut fx = DMatrix::zeros(p, n);
    let mut step = vec![0.0; p + 1];
    for i in 1..=p {
        fx.row_mut(i - 1).copy_from(&(c * &powers[i]));
        step[i] = step[i - 1] + (c * &powers[i - 1] * b)[(0, 0)];
    }
    let fw = (1..=p)
        .map(|i| {
            (0..i)
                .map(|j| {
                    let row = c * &powers[i - 1 - j] * g;
                    std::array::from_fn(|q| row[(0, q)])
                })
                .collect()
        })
        .collect();
    // Θ_{i,l}: move l affects every later output, ramped in over its own period and held
    // after it: S_{i−l−1} + C A^{i−l−1} Γ₁ (= S_{i−l} for a hold).
    let mut theta = DMatrix::zeros(p, mm);
    for i in 1..=p {
        for l in 0..mm.min(i) {
            let k = i - l - 1;
            theta[(i - 1, l)] = step[k] + (c * &powers[k] * b1)[(0, 0)];
        }
    }
    Prediction {
        fx,
        step,
        fw,
        theta,
    }
}

/// The QP over [Δu; ε]: the cost ½ zᵀ P z + qᵀ z with P = 2·blkdiag(H, λ_ε), and the
/// constraint rows u upper (M), u lower (M), Δu upper (M), Δu lower (M), ξ upper (p),
/// ξ lower (p), ε ≥ 0 (1).
fn qp_matrices(
    h: &DMatrix<f64>,
    theta: &DMatrix<f64>,
    s: &MpcSettings,
) -> (DMatrix<f64>, DMatrix<f64>) {
    let (p, mm) = (s.horizon_p, s.horizon_m);
    let nv = mm + 1;
    let mut pq = DMatrix::zeros(nv, nv);
    pq.view_mut((0, 0), (mm, mm)).copy_from(&(h * 2.0));
    pq[(mm, mm)] = 2.0 * s.slack_weight;
    let nc = 4 * mm + 2 * p + 1;
    let mut ac = DMatrix::zeros(nc, nv);
    for i in 0..mm {
        for l in 0..=i {
            ac[(i, l)] = 1.0;
            ac[(mm + i, l)] = -1.0;
        }
        ac[(2 * mm + i, i)] = 1.0;
        ac[(3 * mm + i, i)] = -1.0;
    }
    for i in 0..p {
        for l in 0..mm {
            ac[(4 * mm + i, l)] = theta[(i, l)];
            ac[(4 * mm + p + i, l)] = -theta[(i, l)];
        }
        ac[(4 * mm + i, mm)] = -1.0;
        ac[(4 * mm + p + i, mm)] = -1.0;
    }
    ac[(nc - 1, mm)] = -1.0;
    (pq, ac)
}

/// The three forms of the QP, indexed by `QpRows as usize`, each set up in Clarabel with the
/// rows it keeps and its variables (the first of [Δu; ε]).
fn qp_forms(
    pq: &DMatrix<f64>,
    ac: &DMatrix<f64>,
    s: &MpcSettings,
    q: &[f64],
    bvec: &[f64],
) -> Result<[QpForm; 3], DesignError> {
    let mm = s.horizon_m;
    let (nc, nv) = (ac.nrows(), ac.ncols());
    // See the module's notes: settings fitted to a QP this small.
    let settings: DefaultSettings<f64> = DefaultSettingsBuilder::default()
        .verbose(false)
        .presolve_enable(false)
        .max_iter(s.max_iter)
        .iterative_refinement_enable(false)
        .equilibrate_enable(false)
        .tol_gap_abs(QP_TOLERANCE)
        .tol_gap_rel(QP_TOLERANCE)
        .tol_feas(QP_TOLERANCE)
        .build()
        .map_err(|e| DesignError(format!("MPC: Clarabel settings: {e}")))?;
    let form = |rows_of: QpRows| {
        let (rows, nvars) = match rows_of {
            QpRows::Full => (0..nc, nv),
            QpRows::Inputs => (0..4 * mm, mm),
            QpRows::Moves => (2 * mm..4 * mm, mm),
        };
        let nr = rows.len();
        let (q, b) = (q[..nvars].to_vec(), bvec[rows.clone()].to_vec());
        let solver = DefaultSolver::new(
            &dense_to_csc(&pq.view((0, 0), (nvars, nvars)).into_owned(), true),
            &q,
            &dense_to_csc(&ac.view((rows.start, 0), (nr, nvars)).into_owned(), false),
            &b,
            &[SupportedConeT::NonnegativeConeT(nr)],
            settings.clone(),
        )
        .map_err(|e| DesignError(format!("MPC: Clarabel set-up ({rows_of:?} QP): {e}")))?;
        Ok::<_, DesignError>(QpForm { solver, q, b, rows })
    };
    Ok([
        form(QpRows::Full)?,
        form(QpRows::Inputs)?,
        form(QpRows::Moves)?,
    ])
}

impl Mpc {
    /// Builds the model, the filter and the QP. `u_max_deg` is the hard input limit.
    pub fn new(
        m: &LinearModel,
        s: &MpcSettings,
        k: &KalmanSettings,
        period: f64,
        u_max_deg: f64,
        input_shape: InputShape,
    ) -> Result<Self, DesignError> {
        let n = 10;
        let (p, mm) = (s.horizon_p, s.horizon_m);
        let Augmented { a, b, b1, g, c } = augmented(m, period, input_shape);
        let l_est = kalman_gain(m, k, &a, &c, period)?;
        let Prediction {
            fx,
            step,
            fw,
            theta,
        } = prediction(&a, &b, &b1, &g, &c, p, mm);
        let h = theta.transpose() * &theta * s.output_weight
            + DMatrix::identity(mm, mm) * s.rate_weight;
        let (pq, ac) = qp_matrices(&h, &theta, s);
        let nv = mm + 1;
        let nc = 4 * mm + 2 * p + 1;
        let q = vec![0.0; nv];
        let bvec = vec![1.0; nc];
        let forms = qp_forms(&pq, &ac, s, &q, &bvec)?;
        Ok(Mpc {
            s: s.clone(),
            u_max: u_max_deg.to_radians(),
            du_max: s.du_max_deg.to_radians(),
            y_max: s.theta_v_max_deg.to_radians(),
            a,
            b,
            b1,
            input_shape,
            g,
            c,
            l_est,
            fx,
            step,
            fw,
            reach: theta
                .row_iter()
                .map(|row| row.iter().map(|t| t.abs()).sum::<f64>() * s.du_max_deg.to_radians())
                .collect(),
            theta,
            h,
            forms,
            x_hat: DMatrix::zeros(n, 1),
            u_prev: 0.0,
            q,
            bvec,
            track_input: k.track_input,
            work: Work::new(n, p),
        })
    }

    /// The free response f (p): the prediction with Δu = 0 from the filtered state.
    pub fn free_response(&self, x_f: &DMatrix<f64>, w: &[[f64; 6]]) -> Vec<f64> {
        let mut f = Vec::with_capacity(self.s.horizon_p);
        self.free_response_into(x_f, w, &mut f, &mut DMatrix::zeros(1, 1));
        f
    }

    /// [`Mpc::free_response`] into `f`, with `one` (1×1) for each row's product.
    fn free_response_into(
        &self,
        x_f: &DMatrix<f64>,
        w: &[[f64; 6]],
        f: &mut Vec<f64>,
        one: &mut DMatrix<f64>,
    ) {
        let p = self.s.horizon_p;
        f.clear();
        for i in 1..=p {
            self.fx.row(i - 1).mul_to(x_f, one);
            let mut v = one[(0, 0)] + self.step[i] * self.u_prev;
            if self.track_input {
                for (j, wj) in w.iter().enumerate().take(i) {
                    v += self.fw[i - 1][j]
                        .iter()
                        .zip(wj)
                        .map(|(a, b)| a * b)
                        .sum::<f64>();
                }
            }
            f.push(v);
        }
    }

    /// The unconstrained optimum Δu* = −H⁻¹ Θᵀ Λ_ξ (f − r), for checking the QP.
    pub fn unconstrained(&self, f: &[f64], r: &[f64]) -> Vec<f64> {
        let e = DMatrix::from_iterator(f.len(), 1, f.iter().zip(r).map(|(a, b)| a - b));
        let g = self.theta.transpose() * e * self.s.output_weight;
        let sol = self
            .h
            .clone()
            .lu()
            .solve(&g)
            .unwrap_or_else(|| g.clone() * f64::NAN);
        sol.iter().map(|v| -v).collect()
    }

    /// Whether the moves `du` from the previous command `u_prev` keep every constraint of the
    /// QP with no slack: |u| ≤ u_max, |Δu| ≤ Δu_max and the prediction |f + Θ Δu| ≤ ξ_max.
    /// Where the unconstrained optimum does, it is the QP's optimum.
    pub fn keeps_constraints(&self, u_prev: f64, f: &[f64], du: &[f64]) -> bool {
        let mut u = u_prev;
        let moves = du.iter().all(|&d| {
            u += d;
            d.abs() <= self.du_max && u.abs() <= self.u_max
        });
        moves
            && f.iter().enumerate().all(|(i, fi)| {
                let y: f64 = fi
                    + du.iter()
                        .enumerate()
                        .map(|(l, d)| self.theta[(i, l)] * d)
                        .sum::<f64>();
                y.abs() <= self.y_max
            })
    }

    /// Filters the measurement: x̂(k|k).
    pub fn filter(&self, xi: f64) -> DMatrix<f64> {
        let innovation = xi - (&self.c * &self.x_hat)[(0, 0)];
        &self.x_hat + &self.l_est * innovation
    }

    /// The rows an update with free response `f` must solve (from the previous command):
    /// * a soft output row i cannot bind when |f_i| + Σ_l |Θ_il| Δu_max ≤ ξ_max, whatever moves
    ///   the move limits allow; when none can, the slack is zero at the optimum (ε ≥ 0 costs
    ///   λ_ε ε² and loosens nothing that binds) and the output rows and ε are left out;
    /// * an input-level row |u_{k+j}| ≤ u_max cannot bind when |u_{k−1}| + (j+1) Δu_max ≤ u_max;
    ///   when none can (j = M−1 is the widest) they are left out too.
    pub fn rows_needed(&self, f: &[f64]) -> QpRows {
        let mm = self.s.horizon_m;
        let outputs_free = f
            .iter()
            .zip(&self.reach)
            .all(|(fi, reach)| fi.abs() + reach <= self.y_max);
        let inputs_free = self.u_prev.abs() + mm as f64 * self.du_max <= self.u_max;
        match (outputs_free, inputs_free) {
            (false, _) => QpRows::Full,
            (true, false) => QpRows::Inputs,
            (true, true) => QpRows::Moves,
        }
    }

    /// Solves the QP for free response `f` and references `r`: (Δu, iterations, solved).
    /// Only the rows that can bind are solved ([`Mpc::rows_needed`]); the optimum is the same.
    pub fn solve(&mut self, f: &[f64], r: &[f64]) -> (Vec<f64>, u32, bool) {
        let rows = self.rows_needed(f);
        self.solve_with(f, r, rows)
    }

    /// Solves the QP in the form `rows`, whether or not the rows left out could bind (for
    /// checking [`Mpc::solve`]).
    pub fn solve_with(&mut self, f: &[f64], r: &[f64], rows: QpRows) -> (Vec<f64>, u32, bool) {
        let mm = self.s.horizon_m;
        let (iterations, solved) = self.solve_in_place(f, r, rows);
        if solved {
            let x = &self.forms[rows as usize].solver.solution.x;
            (x[..mm].to_vec(), iterations, true)
        } else {
            (vec![0.0; mm], iterations, false)
        }
    }

    /// Solves the QP in the form `rows`, leaving the moves in that form's solution:
    /// (iterations, solved).
    fn solve_in_place(&mut self, f: &[f64], r: &[f64], rows: QpRows) -> (u32, bool) {
        let (p, mm) = (self.s.horizon_p, self.s.horizon_m);
        let lam = self.s.output_weight;
        for l in 0..mm {
            self.q[l] = 2.0
                * lam
                * (0..p)
                    .map(|i| self.theta[(i, l)] * (f[i] - r[i]))
                    .sum::<f64>();
        }
        self.q[mm] = 0.0;
        for i in 0..mm {
            self.bvec[i] = self.u_max - self.u_prev;
            self.bvec[mm + i] = self.u_max + self.u_prev;
            self.bvec[2 * mm + i] = self.du_max;
            self.bvec[3 * mm + i] = self.du_max;
        }
        for (i, fi) in f.iter().enumerate().take(p) {
            self.bvec[4 * mm + i] = self.y_max - fi;
            self.bvec[4 * mm + p + i] = self.y_max + fi;
        }
        let nc = self.bvec.len();
        self.bvec[nc - 1] = 0.0;
        let form = &mut self.forms[rows as usize];
        let nv = form.q.len();
        form.q.copy_from_slice(&self.q[..nv]);
        form.b.copy_from_slice(&self.bvec[form.rows.clone()]);
        if form.solver.update_q(&form.q).is_err() || form.solver.update_b(&form.b).is_err() {
            return (0, false);
        }
        form.solver.solve();
        let sol = &form.solver.solution;
        let solved = matches!(
            sol.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) && sol.x.iter().all(|v| v.is_finite());
        (sol.iterations, solved)
    }

    /// One period: filter, optimise, apply the first move (eq 35), predict. Allocates nothing
    /// (the buffers are the controller's, `Work`).
    pub fn step(&mut self, input: &MpcInput) -> MpcUpdate {
        let mut work = std::mem::replace(&mut self.work, Work::new(0, 0));
        let Work {
            x_f,
            next,
            gw,
            w,
            one,
            f,
        } = &mut work;
        // The filter (as `filter`): x̂(k|k) = x̂ + L_est (ξ − C x̂).
        self.c.mul_to(&self.x_hat, one);
        let innovation = input.xi - one[(0, 0)];
        for ((xf, xh), l) in x_f.iter_mut().zip(self.x_hat.iter()).zip(self.l_est.iter()) {
            *xf = xh + l * innovation;
        }
        self.free_response_into(x_f, input.w, f, one);
        let rows = self.rows_needed(f);
        let (iterations, solved) = self.solve_in_place(f, input.r, rows);
        let du_first = if solved {
            self.forms[rows as usize].solver.solution.x[0]
        } else {
            0.0
        };
        // Clamp against rounding at the limits (the QP holds them to ~1e-8 rad).
        let du0 = du_first.clamp(-self.du_max, self.du_max);
        let u_old = self.u_prev;
        let u = (u_old + du0).clamp(-self.u_max, self.u_max);
        self.u_prev = u;
        // x̂(k+1|k) = A x̂(k|k) + B u(k−1) + Γ₁ (u − u(k−1)) [+ Γ ω], summed in that order.
        self.a.mul_to(x_f, next);
        let du = u - u_old;
        for ((n, b), b1) in next.iter_mut().zip(self.b.iter()).zip(self.b1.iter()) {
            *n = (*n + b * u_old) + b1 * du;
        }
        if self.track_input {
            if let Some(wk) = input.w.first() {
                w.copy_from_slice(wk);
                self.g.mul_to(w, gw);
                for (n, g) in next.iter_mut().zip(gw.iter()) {
                    *n += g;
                }
            }
        }
        std::mem::swap(&mut self.x_hat, next);
        self.c.mul_to(x_f, one);
        let theta_v_hat = one[(0, 0)];
        self.work = work;
        MpcUpdate {
            u,
            theta_v_hat,
            iterations,
            solved,
        }
    }

    /// Horizon p.
    pub fn horizon(&self) -> usize {
        self.s.horizon_p
    }

    /// Whether the reference over the horizon comes from the track database.
    pub fn preview(&self) -> bool {
        self.s.preview
    }

    /// Sets the previous command u(k−1) (rad).
    pub fn set_previous(&mut self, u: f64) {
        self.u_prev = u;
    }
}

//! Design-time linear algebra written for this project: zero-order-hold discretisation, the
//! continuous algebraic Riccati equation (CARE) and the discrete one (DARE).
//!
//! * CARE `AᵀP + PA + Q − P B R⁻¹ Bᵀ P = 0` (paper eqs 25 and 28): matrix sign function of the
//!   Hamiltonian with determinant scaling, then Newton–Kleinman refinement (each Newton step a
//!   Lyapunov equation solved exactly through its Kronecker form). The residual is returned so
//!   callers and tests can check it.
//! * DARE `P = AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q`: structure-preserving doubling.
//! * ZOH: `exp([[A, B], [0, 0]]·T)`; process noise by Van Loan's method.
//!
//! Sizes here are at most 20×20 (the Hamiltonian of the 10-state LQI), so dense `DMatrix` is
//! the right tool; these run once at start-up.

use nalgebra::DMatrix;

/// Failure of a design computation, with what failed.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignError(pub String);

impl std::fmt::Display for DesignError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

fn inv(m: &DMatrix<f64>, what: &str) -> Result<DMatrix<f64>, DesignError> {
    m.clone()
        .try_inverse()
        .ok_or_else(|| DesignError(format!("{what}: singular matrix")))
}

/// Zero-order-hold discretisation of `ẋ = A x + B u` at period `t`: returns `(A_d, B_d)`.
pub fn c2d(a: &DMatrix<f64>, b: &DMatrix<f64>, t: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut big = DMatrix::zeros(n + m, n + m);
    big.view_mut((0, 0), (n, n)).copy_from(&(a * t));
    big.view_mut((0, n), (n, m)).copy_from(&(b * t));
    let e = big.exp();
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

/// Discrete covariance of continuous white process noise of intensity `qc` over period `t`
/// (Van Loan): `Q_d = ∫₀ᵀ e^{Aτ} Q_c e^{Aᵀτ} dτ`.
pub fn van_loan(a: &DMatrix<f64>, qc: &DMatrix<f64>, t: f64) -> DMatrix<f64> {
    let n = a.nrows();
    let mut m = DMatrix::zeros(2 * n, 2 * n);
    m.view_mut((0, 0), (n, n)).copy_from(&(-a * t));
    m.view_mut((0, n), (n, n)).copy_from(&(qc * t));
    m.view_mut((n, n), (n, n)).copy_from(&(a.transpose() * t));
    let e = m.exp();
    let f22 = e.view((n, n), (n, n)).into_owned();
    let g12 = e.view((0, n), (n, n)).into_owned();
    let q = f22.transpose() * g12;
    (&q + q.transpose()) * 0.5
}

/// CARE residual `AᵀP + PA + Q − P B R⁻¹ Bᵀ P`.
pub fn care_residual(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    p: &DMatrix<f64>,
) -> DMatrix<f64> {
    let rinv = r.clone().try_inverse().unwrap_or_else(|| r * f64::NAN);
    a.transpose() * p + p * a + q - p * b * rinv * b.transpose() * p
}

/// Solves the Lyapunov equation `Fᵀ X + X F + W = 0` through its Kronecker form.
fn lyap(f: &DMatrix<f64>, w: &DMatrix<f64>) -> Result<DMatrix<f64>, DesignError> {
    let n = f.nrows();
    let id = DMatrix::<f64>::identity(n, n);
    // vec(FᵀX + XF) = (I ⊗ Fᵀ + Fᵀ ⊗ I) vec(X)
    let k = id.kronecker(&f.transpose()) + f.transpose().kronecker(&id);
    let rhs = -DMatrix::from_column_slice(n * n, 1, w.as_slice());
    let x = k
        .lu()
        .solve(&rhs)
        .ok_or_else(|| DesignError("Lyapunov equation: singular operator".into()))?;
    let x = DMatrix::from_column_slice(n, n, x.as_slice());
    Ok((&x + x.transpose()) * 0.5)
}

/// Stabilising solution of the CARE `AᵀP + PA + Q − P B R⁻¹ Bᵀ P = 0`.
pub fn care(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>, DesignError> {
    let n = a.nrows();
    let rinv = inv(r, "CARE: R")?;
    let s = b * &rinv * b.transpose();
    // Hamiltonian H = [[A, −S], [−Q, −Aᵀ]]; its stable invariant subspace is span [I; P].
    let mut z = DMatrix::zeros(2 * n, 2 * n);
    z.view_mut((0, 0), (n, n)).copy_from(a);
    z.view_mut((0, n), (n, n)).copy_from(&(-&s));
    z.view_mut((n, 0), (n, n)).copy_from(&(-q));
    z.view_mut((n, n), (n, n)).copy_from(&(-a.transpose()));
    let id2 = DMatrix::<f64>::identity(2 * n, 2 * n);
    let mut converged = false;
    for _ in 0..100 {
        let zi = inv(
            &z,
            "CARE: Hamiltonian has an eigenvalue on the imaginary axis",
        )?;
        let det = z.determinant().abs();
        let c = if det.is_finite() && det > 0.0 {
            det.powf(-1.0 / (2 * n) as f64)
        } else {
            1.0
        };
        let next = (&z * c + zi / c) * 0.5;
        let change = (&next - &z).norm() / next.norm();
        z = next;
        if change < 1e-13 {
            converged = true;
            break;
        }
    }
    if !converged && (&z * &z - &id2).norm() > 1e-6 * (2 * n) as f64 {
        return Err(DesignError("CARE: sign iteration did not converge".into()));
    }
    // (sign(H) + I) [I; P] = 0  →  [W12; W22 + I] P = −[W11 + I; W21]
    let w11 = z.view((0, 0), (n, n)).into_owned();
    let w12 = z.view((0, n), (n, n)).into_owned();
    let w21 = z.view((n, 0), (n, n)).into_owned();
    let w22 = z.view((n, n), (n, n)).into_owned();
    let id = DMatrix::<f64>::identity(n, n);
    let mut lhs = DMatrix::zeros(2 * n, n);
    lhs.view_mut((0, 0), (n, n)).copy_from(&w12);
    lhs.view_mut((n, 0), (n, n)).copy_from(&(w22 + &id));
    let mut rhs = DMatrix::zeros(2 * n, n);
    rhs.view_mut((0, 0), (n, n)).copy_from(&(-(w11 + &id)));
    rhs.view_mut((n, 0), (n, n)).copy_from(&(-w21));
    let lt = lhs.transpose();
    let mut p = (&lt * &lhs)
        .lu()
        .solve(&(&lt * rhs))
        .ok_or_else(|| DesignError("CARE: rank-deficient invariant subspace".into()))?;
    p = (&p + p.transpose()) * 0.5;
    // Newton–Kleinman refinement: (A − S P)ᵀ X + X (A − S P) + Q + P S P = 0.
    for _ in 0..4 {
        let f = a - &s * &p;
        let w = q + &p * &s * &p;
        let next = lyap(&f, &w)?;
        let change = (&next - &p).norm() / next.norm().max(1e-300);
        p = next;
        if change < 1e-14 {
            break;
        }
    }
    if p.iter().any(|v| !v.is_finite()) {
        return Err(DesignError("CARE: non-finite solution".into()));
    }
    Ok(p)
}

/// DARE residual `AᵀPA − AᵀPB (R + BᵀPB)⁻¹ BᵀPA + Q − P`.
pub fn dare_residual(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    p: &DMatrix<f64>,
) -> DMatrix<f64> {
    let m = (r + b.transpose() * p * b)
        .try_inverse()
        .unwrap_or_else(|| r * f64::NAN);
    a.transpose() * p * a - a.transpose() * p * b * m * b.transpose() * p * a + q - p
}

/// Stabilising solution of the DARE by the structure-preserving doubling algorithm.
pub fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<DMatrix<f64>, DesignError> {
    let n = a.nrows();
    let id = DMatrix::<f64>::identity(n, n);
    let mut ak = a.clone();
    let mut gk = b * inv(r, "DARE: R")? * b.transpose();
    let mut hk = q.clone();
    for _ in 0..200 {
        let w = inv(&(&id + &gk * &hk), "DARE: I + G H")?;
        let a_next = &ak * &w * &ak;
        let g_next = &gk + &ak * &w * &gk * ak.transpose();
        let h_next = &hk + ak.transpose() * &hk * &w * &ak;
        let change = (&h_next - &hk).norm() / h_next.norm().max(1e-300);
        ak = a_next;
        gk = (&g_next + g_next.transpose()) * 0.5;
        hk = (&h_next + h_next.transpose()) * 0.5;
        if change < 1e-14 {
            return Ok(hk);
        }
    }
    Err(DesignError("DARE: doubling did not converge".into()))
}

/// Largest modulus among the eigenvalues of a square matrix.
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    m.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// Largest real part among the eigenvalues of a square matrix.
pub fn spectral_abscissa(m: &DMatrix<f64>) -> f64 {
    m.complex_eigenvalues()
        .iter()
        .map(|z| z.re)
        .fold(f64::NEG_INFINITY, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_riccati_equations_match_their_closed_forms() {
        // CARE, scalar: 2ap + q − p²b²/r = 0 → p = r(a + √(a² + b²q/r))/b².
        let (a, b, q, r) = (0.7, 2.0, 3.0, 0.5);
        let m = |v: f64| DMatrix::from_element(1, 1, v);
        let p = care(&m(a), &m(b), &m(q), &m(r)).unwrap()[(0, 0)];
        let exact = r * (a + (a * a + b * b * q / r).sqrt()) / (b * b);
        assert!((p - exact).abs() < 1e-12 * exact, "{p} vs {exact}");
        // DARE, scalar: p = a²p − a²p²b²/(r + b²p) + q, the positive root of
        // b²p² + (r − a²r − b²q)p − qr = 0.
        let (a, b, q, r) = (1.2, 0.5, 2.0, 1.0);
        let p = dare(&m(a), &m(b), &m(q), &m(r)).unwrap()[(0, 0)];
        let (qa, qb, qc) = (b * b, r - a * a * r - b * b * q, -q * r);
        let exact = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
        assert!((p - exact).abs() < 1e-10 * exact, "{p} vs {exact}");
    }

    #[test]
    fn zoh_of_an_integrator_and_a_first_order_lag() {
        // ẋ = −x/τ + u/τ: A_d = e^{−T/τ}, B_d = 1 − e^{−T/τ}.
        let tau = 0.02;
        let (ad, bd) = c2d(
            &DMatrix::from_element(1, 1, -1.0 / tau),
            &DMatrix::from_element(1, 1, 1.0 / tau),
            0.05,
        );
        let e = (-0.05f64 / tau).exp();
        assert!((ad[(0, 0)] - e).abs() < 1e-14);
        assert!((bd[(0, 0)] - (1.0 - e)).abs() < 1e-14);
        // Van Loan, scalar: ∫ e^{2aτ} q dτ = q (e^{2aT} − 1)/(2a).
        let (a, q, t) = (-3.0, 2.0, 0.1);
        let qd = van_loan(
            &DMatrix::from_element(1, 1, a),
            &DMatrix::from_element(1, 1, q),
            t,
        )[(0, 0)];
        assert!((qd - q * ((2.0 * a * t).exp() - 1.0) / (2.0 * a)).abs() < 1e-13);
    }
}

//! The covariance matrix adaptation evolution strategy, CMA-ES, as N. Hansen, "The CMA
//! Evolution Strategy: A Tutorial", arXiv:1604.00772 (2016) gives it: (μ/μ_W, λ) selection
//! with positive recombination weights, cumulative step-size adaptation and the rank-one and
//! rank-μ covariance updates, with the tutorial's default parameters (its Table 1). It
//! maximises; the caller evaluates each generation (in parallel) and hands back the values in
//! the order of the points.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// The state of a search in `n` dimensions.
pub struct CmaEs {
    n: usize,
    /// Population size λ.
    pub lambda: usize,
    mu: usize,
    weights: DVector<f64>,
    mu_eff: f64,
    c_c: f64,
    c_sigma: f64,
    c_1: f64,
    c_mu: f64,
    d_sigma: f64,
    chi_n: f64,
    mean: DVector<f64>,
    sigma: f64,
    c: DMatrix<f64>,
    b: DMatrix<f64>,
    d: DVector<f64>,
    p_c: DVector<f64>,
    p_sigma: DVector<f64>,
    generation: u64,
    rng: ChaCha8Rng,
    /// The last generation's steps y = (x − m) / σ, for the update.
    ys: Vec<DVector<f64>>,
}

impl CmaEs {
    /// A search from `mean` with step size `sigma`, its random draws from `seed`.
    pub fn new(mean: Vec<f64>, sigma: f64, seed: u64) -> CmaEs {
        let n = mean.len().max(1);
        let nf = n as f64;
        // Table 1 of the tutorial.
        let lambda = 4 + (3.0 * nf.ln()).floor() as usize;
        let mu = lambda / 2;
        let raw: Vec<f64> = (1..=mu)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
            .collect();
        let sum: f64 = raw.iter().sum();
        let weights = DVector::from_iterator(mu, raw.iter().map(|w| w / sum));
        let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
        let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
        let c_1 = 2.0 / ((nf + 1.3).powi(2) + mu_eff);
        let c_mu =
            (1.0 - c_1).min(2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff));
        let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
        let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        let mut m = mean;
        m.resize(n, 0.0);
        CmaEs {
            n,
            lambda,
            mu,
            weights,
            mu_eff,
            c_c,
            c_sigma,
            c_1,
            c_mu,
            d_sigma,
            chi_n,
            mean: DVector::from_vec(m),
            sigma,
            c: DMatrix::identity(n, n),
            b: DMatrix::identity(n, n),
            d: DVector::from_element(n, 1.0),
            p_c: DVector::zeros(n),
            p_sigma: DVector::zeros(n),
            generation: 0,
            rng: ChaCha8Rng::seed_from_u64(seed),
            ys: Vec::new(),
        }
    }

    /// The next generation's λ points, x = m + σ B D z with z ~ N(0, I) (eq. 38-40).
    pub fn ask(&mut self) -> Vec<Vec<f64>> {
        self.ys.clear();
        let mut out = Vec::with_capacity(self.lambda);
        for _ in 0..self.lambda {
            let z = DVector::from_fn(self.n, |_, _| StandardNormal.sample(&mut self.rng));
            let y = &self.b * self.d.component_mul(&z);
            let x = &self.mean + self.sigma * &y;
            self.ys.push(y);
            out.push(x.iter().copied().collect());
        }
        out
    }

    /// Takes the values of the points [`CmaEs::ask`] gave, in their order (larger is
    /// better; NaN counts as the worst), and moves the distribution (eq. 41-47).
    pub fn tell(&mut self, values: &[f64]) {
        let mut idx: Vec<usize> = (0..self.ys.len()).collect();
        let key = |v: f64| if v.is_nan() { f64::NEG_INFINITY } else { v };
        // Best first; ties keep the order of the points.
        idx.sort_by(|&a, &b| key(values[b]).total_cmp(&key(values[a])).then(a.cmp(&b)));
        let mut y_w = DVector::zeros(self.n);
        for (w, &i) in self.weights.iter().zip(&idx[..self.mu]) {
            y_w += *w * &self.ys[i];
        }
        self.mean += self.sigma * &y_w;
        // C^{-1/2} = B D^{-1} Bᵀ.
        let inv_sqrt =
            &self.b * DMatrix::from_diagonal(&self.d.map(|x| 1.0 / x)) * self.b.transpose();
        self.p_sigma = (1.0 - self.c_sigma) * &self.p_sigma
            + (self.c_sigma * (2.0 - self.c_sigma) * self.mu_eff).sqrt() * (inv_sqrt * &y_w);
        self.generation += 1;
        let norm = self.p_sigma.norm();
        let decay = (1.0 - (1.0 - self.c_sigma).powi(2 * self.generation as i32)).sqrt();
        let h_sigma = if norm / decay < (1.4 + 2.0 / (self.n as f64 + 1.0)) * self.chi_n {
            1.0
        } else {
            0.0
        };
        self.p_c = (1.0 - self.c_c) * &self.p_c
            + h_sigma * (self.c_c * (2.0 - self.c_c) * self.mu_eff).sqrt() * &y_w;
        let mut rank_mu = DMatrix::zeros(self.n, self.n);
        for (w, &i) in self.weights.iter().zip(&idx[..self.mu]) {
            rank_mu += *w * &self.ys[i] * self.ys[i].transpose();
        }
        let delta = (1.0 - h_sigma) * self.c_c * (2.0 - self.c_c);
        self.c = (1.0 - self.c_1 - self.c_mu + self.c_1 * delta) * &self.c
            + self.c_1 * &self.p_c * self.p_c.transpose()
            + self.c_mu * rank_mu;
        self.sigma *= ((self.c_sigma / self.d_sigma) * (norm / self.chi_n - 1.0)).exp();
        // Symmetric, then decomposed: C = B D² Bᵀ.
        let sym = (&self.c + self.c.transpose()) * 0.5;
        self.c = sym.clone();
        let eig = SymmetricEigen::new(sym);
        self.b = eig.eigenvectors;
        self.d = eig.eigenvalues.map(|e| e.max(1e-20).sqrt());
    }

    /// The step size σ.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a concave quadratic with its maximum at (0.3, −0.2, 0.5, 0.1), the mean reaches
    /// the maximum: the updates move the distribution uphill and shrink it.
    #[test]
    fn cma_es_finds_the_maximum_of_a_quadratic() {
        let top = [0.3, -0.2, 0.5, 0.1];
        let f = |x: &[f64]| {
            -x.iter()
                .zip(top)
                .map(|(a, b)| (a - b) * (a - b) * 10.0)
                .sum::<f64>()
        };
        let mut es = CmaEs::new(vec![0.0; 4], 0.5, 7);
        for _ in 0..150 {
            let xs = es.ask();
            let v: Vec<f64> = xs.iter().map(|x| f(x)).collect();
            es.tell(&v);
        }
        for (m, t) in es.mean.iter().zip(top) {
            assert!((m - t).abs() < 1e-4, "mean {m} vs {t}");
        }
        assert!(es.sigma() < 1e-3);
    }
}

//! Running safety of the whole car from the plant's samples (`FromPlant::car`: the wheel-rail
//! forces of the four wheelsets, each tick), assessed with
//! [`vehicle_model::full_car::RunningSafety`] against EN 14363's limits (docs/model.md, "The
//! whole car", running safety): the dynamic quantities ((Y/Q)_2m, (ΣY)_2m, ΔQ/Q_0) over the
//! whole run, the quasi-static ones (Y_qst, Q_qst, medians) over the steady curve.

use serde::Serialize;
use vehicle_model::full_car::safety::{Assessed, RunningSafety, SafetyLimits};
use vehicle_model::full_car::{WheelForces, NW};

/// Values per sample in `FromPlant::car`: five forces per wheelset, then the body's lateral
/// acceleration at three places.
pub use tiltsim_protocol::msg::CAR_VALUES;
const _: () = assert!(
    CAR_VALUES == 5 * NW + 3,
    "FromPlant::car holds the whole car's values"
);

/// The wheel-rail forces of one sample's `car` values.
pub fn wheel_forces(car: &[f64; CAR_VALUES]) -> [WheelForces; NW] {
    std::array::from_fn(|j| {
        let f = &car[5 * j..5 * j + 5];
        WheelForces {
            sum_y: f[0],
            y_plus: f[1],
            y_minus: f[2],
            q_plus: f[3],
            q_minus: f[4],
        }
    })
}

/// One running-safety quantity of a run: its worst value, where, its limit.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SafetyValue {
    /// `(Y/Q)_2m`, `(SumY)_2m` (the track shift force, against Prud'homme's limit), `dQ/Q0`,
    /// `Y_qst`, `Q_qst`.
    pub quantity: &'static str,
    /// Worst value (N, or a ratio); `null` in JSON when a wheel lifted (Q ≤ 0: Y/Q infinite,
    /// the linear model beyond its range).
    pub value: f64,
    /// The limit (same unit).
    pub limit: f64,
    /// value / limit.
    pub utilisation: f64,
    /// Wheelset of the worst value, 1 the leading one.
    pub wheelset: usize,
    /// Whether the limit is exceeded.
    pub exceeded: bool,
    /// Where it was assessed: `whole run` or `steady curve`.
    pub over: &'static str,
    /// The limit's source.
    pub source: &'static str,
}

impl SafetyValue {
    fn of(a: &Assessed, over: &'static str) -> Self {
        let u = a.utilisation();
        SafetyValue {
            quantity: a.name,
            value: a.value,
            limit: a.limit,
            utilisation: u,
            wheelset: a.wheelset + 1,
            exceeded: u > 1.0,
            over,
            source: a.source,
        }
    }
}

/// The running-safety flag: raised when any limit is exceeded.
#[derive(Debug, Clone, Serialize, Default, PartialEq)]
pub struct RunningSafetyFlag {
    /// Whether a limit is exceeded.
    pub raised: bool,
    /// The quantities beyond their limits.
    pub exceeded: Vec<&'static str>,
    /// The quantity closest to (or furthest beyond) its limit.
    pub binding: &'static str,
    /// Its utilisation (value / limit).
    pub binding_utilisation: f64,
}

const DYNAMIC: [&str; 3] = ["(Y/Q)_2m", "(SumY)_2m", "dQ/Q0"];
const QUASI_STATIC: [&str; 2] = ["Y_qst", "Q_qst"];

/// Assesses the samples `car` taken every `dt` (s) at speed `v` (m/s), static wheel load `q0`
/// (N): the dynamic quantities over all of them, the quasi-static ones over `steady` (the
/// samples on the steady curve; none when it is empty). None without samples.
pub fn assess(
    car: &[[f64; CAR_VALUES]],
    steady: std::ops::Range<usize>,
    v: f64,
    dt: f64,
    q0: f64,
) -> Option<(Vec<SafetyValue>, RunningSafetyFlag)> {
    let lim = SafetyLimits::default();
    let collect = |s: &[[f64; CAR_VALUES]]| {
        let mut rs = RunningSafety::new();
        for c in s {
            rs.push(wheel_forces(c));
        }
        rs.assess(&lim, v, dt, q0)
    };
    let all = collect(car)?;
    let mut out: Vec<SafetyValue> = all
        .iter()
        .filter(|a| DYNAMIC.contains(&a.name))
        .map(|a| SafetyValue::of(a, "whole run"))
        .collect();
    if let Some(curve) = car.get(steady).and_then(collect) {
        out.extend(
            curve
                .iter()
                .filter(|a| QUASI_STATIC.contains(&a.name))
                .map(|a| SafetyValue::of(a, "steady curve")),
        );
    }
    let binding = out
        .iter()
        .max_by(|a, b| a.utilisation.total_cmp(&b.utilisation))?;
    let flag = RunningSafetyFlag {
        raised: out.iter().any(|a| a.exceeded),
        exceeded: out
            .iter()
            .filter(|a| a.exceeded)
            .map(|a| a.quantity)
            .collect(),
        binding: binding.quantity,
        binding_utilisation: binding.utilisation,
    };
    Some((out, flag))
}

/// Comfort at one place along the car (`[comfort]`'s measures with the body's lateral
/// acceleration at that place).
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct CarPlace {
    /// `leading bogie`, `centre`, `trailing bogie`.
    pub place: &'static str,
    /// Distance ahead of the body's centre (m).
    pub x_m: f64,
    /// P_CT standing, EN 12299 evaluation (%).
    pub p_ct_standing: f64,
    /// P_CT seated, EN 12299 evaluation (%).
    pub p_ct_seated: f64,
    /// P_CT standing from whole-run peaks, the paper's evaluation (%).
    pub p_ct_paper_standing: f64,
    /// Mean comfort index N_MV, lateral part (on the centre line roll adds no vertical part).
    pub n_mv_lateral: f64,
    /// Largest |ÿ| (%g).
    pub lat_acc_peak_pct_g: f64,
}

/// The whole car's part of `summary.json`.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct FullCarReport {
    /// Running safety, worst value of each quantity over the wheelsets.
    pub running_safety: Vec<SafetyValue>,
    /// Comfort over the leading bogie, at the centre and over the trailing bogie.
    pub comfort_along_car: Vec<CarPlace>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples at rest: every wheel at its static load, no lateral force. Nothing is used,
    /// no flag; the worst Y/Q is 0 and ΔQ/Q_0 is 0.
    #[test]
    fn a_car_at_rest_uses_nothing() {
        let q0 = 50e3;
        let mut c = [0.0; CAR_VALUES];
        for j in 0..NW {
            c[5 * j + 3] = q0;
            c[5 * j + 4] = q0;
        }
        let (v, flag) = assess(&[c; 500], 0..500, 40.0, 1e-3, q0).unwrap();
        assert_eq!(v.len(), 5);
        assert!(!flag.raised);
        for q in &v {
            if q.quantity != "Q_qst" {
                assert_eq!(q.value, 0.0, "{}", q.quantity);
            }
        }
    }

    /// A wheel of the third wheelset pushed outwards by 40 kN on a 50 kN load (Y/Q 0.8 is
    /// the limit; 0.9 here) for the whole record: the flag is raised and names Y/Q at
    /// wheelset 3.
    #[test]
    fn a_quotient_beyond_the_limit_is_flagged_at_its_wheelset() {
        let q0 = 50e3;
        let mut c = [0.0; CAR_VALUES];
        for j in 0..NW {
            c[5 * j + 3] = q0;
            c[5 * j + 4] = q0;
        }
        // −y wheel: the rail pushes it towards +y (flange climbing on the −y rail).
        c[5 * 2 + 2] = 45e3;
        c[5 * 2] = 45e3;
        let (v, flag) = assess(&[c; 500], 0..0, 40.0, 1e-3, q0).unwrap();
        let yq = v.iter().find(|q| q.quantity == "(Y/Q)_2m").unwrap();
        assert!((yq.value - 0.9).abs() < 1e-12);
        assert_eq!(yq.wheelset, 3);
        assert!(yq.exceeded && flag.raised && flag.exceeded.contains(&"(Y/Q)_2m"));
        // No steady curve: no quasi-static values.
        assert!(v.iter().all(|q| q.over == "whole run"));
    }
}

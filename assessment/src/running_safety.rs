//! Running safety of the whole car from the plant's samples (`FromPlant::car`: the wheel-rail
//! forces of the four wheelsets, each tick), assessed with
//! [`vehicle_model::full_car::RunningSafety`] against EN 14363's limits (docs/model.md, "The
//! whole car", running safety): the dynamic quantities ((Y/Q)_2m, (ΣY)_2m, ΔQ/Q_0) over the
//! whole run, the quasi-static ones (Y_qst, Q_qst, medians) over the steady curve.

use serde::Serialize;
use vehicle_model::full_car::safety::{
    assessed, window_samples, Assessed, DynamicStream, QuasiStaticStream, RunningSafety,
    SafetyLimits,
};
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
/// samples on the steady curve; none when it is empty). None without samples. The whole
/// record at once: [`Stream`] gives the same values holding a bounded part of it.
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
    let curve = car.get(steady).and_then(collect);
    report(&all, curve.as_deref())
}

/// The summary's values and the flag: the dynamic quantities of `all`, the quasi-static ones
/// of `curve`.
fn report(
    all: &[Assessed],
    curve: Option<&[Assessed]>,
) -> Option<(Vec<SafetyValue>, RunningSafetyFlag)> {
    let mut out: Vec<SafetyValue> = all
        .iter()
        .filter(|a| DYNAMIC.contains(&a.name))
        .map(|a| SafetyValue::of(a, "whole run"))
        .collect();
    if let Some(curve) = curve {
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

/// The running safety of a run assessed as its samples arrive: [`assess`]'s values, bit for
/// bit, holding the 2 m windows (a few dozen samples per wheel) and the steady curve's
/// samples (for its exact medians), not the run's.
#[derive(Debug, Clone)]
pub struct Stream {
    dynamic: DynamicStream,
    curve: QuasiStaticStream,
    steady: std::ops::Range<usize>,
    k: usize,
    q0: f64,
}

impl Stream {
    /// An assessment at speed `v` (m/s), tick `dt` (s), static wheel load `q0` (N), the
    /// quasi-static values over the samples whose index is in `steady`.
    pub fn new(steady: std::ops::Range<usize>, v: f64, dt: f64, q0: f64) -> Self {
        let n = window_samples(&SafetyLimits::default(), v, dt);
        Stream {
            dynamic: DynamicStream::new(n, q0),
            curve: QuasiStaticStream::new(),
            steady,
            k: 0,
            q0,
        }
    }
    /// Adds the next sample.
    pub fn push(&mut self, car: &[f64; CAR_VALUES]) {
        let f = wheel_forces(car);
        self.dynamic.push(&f);
        if self.steady.contains(&self.k) {
            self.curve.push(&f);
        }
        self.k += 1;
    }
    /// Samples handed over.
    pub fn len(&self) -> usize {
        self.k
    }
    /// Whether none was handed over.
    pub fn is_empty(&self) -> bool {
        self.k == 0
    }
    /// Values held (window and steady-curve samples): bounded by the window and the curve,
    /// whatever the run's length.
    pub fn held(&self) -> usize {
        self.dynamic.held() + self.curve.held()
    }
    /// The summary's values and the flag, as [`assess`] gives them; None without samples.
    pub fn finish(&self) -> Option<(Vec<SafetyValue>, RunningSafetyFlag)> {
        let [y_q, sum_y, dq] = self.dynamic.finish()?;
        let qst = self.curve.finish();
        let [y, q] = qst.unwrap_or([(f64::NAN, 0); 2]);
        let all = assessed(&SafetyLimits::default(), self.q0, [y_q, sum_y, dq, y, q]);
        report(&all, qst.map(|_| &all[..]))
    }
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

    /// Forces from a fixed pseudo-random sequence (a 64-bit LCG), wheels lifted now and then
    /// (Q ≤ 0: infinite Y/Q), records shorter and longer than the window, steady sections
    /// empty, inside and running past the record: the streamed assessment gives the
    /// whole-record one's values bit for bit.
    #[test]
    fn the_stream_gives_the_whole_record_values() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let q0 = 50e3;
        for (len, steady, lifted) in [
            (7, 0..7, 0.0),
            (400, 100..300, 0.0),
            (400, 0..0, 0.0),
            (1000, 600..2000, 0.002),
            (1000, 200..900, 0.01),
        ] {
            let car: Vec<[f64; CAR_VALUES]> = (0..len)
                .map(|_| {
                    std::array::from_fn(|i| {
                        let x = next();
                        if i % 5 >= 3 && i < 5 * NW {
                            if x < lifted {
                                -1e3
                            } else {
                                q0 * (0.5 + x)
                            }
                        } else {
                            40e3 * (x - 0.4)
                        }
                    })
                })
                .collect();
            // 40 m/s, 1 ms: windows of 50 samples.
            let batch = assess(
                &car,
                steady.start.min(len)..steady.end.min(len),
                40.0,
                1e-3,
                q0,
            );
            let mut stream = Stream::new(steady.clone(), 40.0, 1e-3, q0);
            for c in &car {
                stream.push(c);
            }
            assert_eq!(
                format!("{:?}", stream.finish()),
                format!("{batch:?}"),
                "{len} samples, steady {steady:?}"
            );
        }
        assert!(Stream::new(0..1, 40.0, 1e-3, q0).finish().is_none());
    }
}

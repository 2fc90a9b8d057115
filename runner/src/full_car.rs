//! The whole car's part of a run (`vehicle.model = "full"`): an observer keeps the plant's
//! `car` values of every row, and after the run's analysis they give the running safety
//! (`summary.json`'s `full_car.running_safety` and `flags.running_safety`) and the comfort
//! over each bogie and at the centre (`full_car.comfort_along_car`).

use std::sync::{Arc, Mutex};

use tiltsim_assessment::comfort::LateralAcceleration;
use tiltsim_assessment::running_safety::{self, CarPlace, FullCarReport, CAR_VALUES};
use tiltsim_formats::table::Rows;
use tiltsim_master::engine::observe::{Observer, Start, Tick};
use tiltsim_master::engine::Summary;
use tiltsim_scenario::scenario::Scenario;
use vehicle_model::full_car::FullCarParams;

/// The `car` values of every row: the outputs at the start, then after every tick.
pub type CarSamples = Arc<Mutex<Vec<[f64; CAR_VALUES]>>>;

/// Keeps the plant's `car` values, one per row of `timeseries.csv`.
pub struct CarObserver {
    samples: CarSamples,
}

impl CarObserver {
    /// An observer and the handle its samples are read through after the run.
    pub fn new() -> (Self, CarSamples) {
        let samples = CarSamples::default();
        (
            CarObserver {
                samples: samples.clone(),
            },
            samples,
        )
    }
    fn push(&self, car: [f64; CAR_VALUES]) {
        if let Ok(mut s) = self.samples.lock() {
            s.push(car);
        }
    }
}

impl Observer for CarObserver {
    fn name(&self) -> &str {
        "full_car"
    }
    fn start(&mut self, start: &Start<'_>) -> std::io::Result<()> {
        self.push(start.plant.car);
        Ok(())
    }
    fn tick(&mut self, tick: &Tick<'_>) -> std::io::Result<()> {
        self.push(tick.plant.car);
        Ok(())
    }
}

/// The rows of the steady curve: the body's centre between the end of the entry transition
/// and the start of the exit one.
fn steady_rows(s: &Scenario, n: usize) -> std::ops::Range<usize> {
    let t = &s.track;
    let ds = s.track.speed() * s.run.dt_s;
    let start = t.straight_before_m + t.transition_m;
    let k0 = (start / ds).ceil() as usize;
    let k1 = ((start + t.curve_m) / ds).floor() as usize + 1;
    k0.min(n)..k1.min(n)
}

/// The places along the body the comfort is given at, in the order of `FromPlant::car`.
const PLACES: [&str; 3] = ["leading bogie", "centre", "trailing bogie"];

/// Comfort at each place: the run's samples for comfort (roll speed, references, deflection:
/// the run's own) with the passenger lateral acceleration, in both forms, the body's at that
/// place, which is what an accelerometer there measures (so the P_CT and the ride's N_MV both
/// take it).
fn comfort_along_car(
    s: &Scenario,
    rows: Rows<'_>,
    car: &[[f64; CAR_VALUES]],
) -> std::io::Result<Vec<CarPlace>> {
    use tiltsim_assessment::comfort::Assessor;
    let mut settings = s.comfort.clone();
    settings.lateral_acceleration = LateralAcceleration::Eq13;
    settings.positions.clear();
    let transitions = tiltsim_report::analysis::transitions(s);
    let body = tiltsim_report::analysis::body(s);
    let mut at: Vec<Assessor> = (0..PLACES.len())
        .map(|_| Assessor::new(s.run.dt_s, &transitions, &settings, body))
        .collect();
    tiltsim_report::analysis::scan(s, rows, |r, x| {
        if let Some(c) = car.get(r.step as usize) {
            for (i, a) in at.iter_mut().enumerate() {
                let acc = c[CAR_VALUES - PLACES.len() + i];
                a.push(&tiltsim_assessment::comfort::Sample {
                    lat_acc: acc,
                    lat_acc_other: acc,
                    ..*x
                });
            }
        }
    })?;
    let p = FullCarParams::from_half(&s.vehicle);
    Ok(at
        .iter()
        .zip(PLACES)
        .zip([p.a, 0.0, -p.a])
        .map(|((a, place), x_m)| {
            let c = a.finish();
            CarPlace {
                place,
                x_m,
                p_ct_standing: c.p_ct_en12299.standing,
                p_ct_seated: c.p_ct_en12299.seated,
                p_ct_paper_standing: c.p_ct_paper.standing,
                n_mv_lateral: c.ride.n_mv_lateral,
                lat_acc_peak_pct_g: c.lat_acc_peak_pct_g,
            }
        })
        .collect())
}

/// Fills the summary's whole-car part from the kept samples and the run's rows (on disk,
/// or `rows` when kept in memory); a note in `analysis_skipped` when they cannot be read.
pub fn assess(s: &Scenario, summary: &mut Summary, samples: &CarSamples, rows: Rows<'_>) {
    // The rows are streamed from the file (or read where kept): only the car's own values
    // are held, one per row (docs/limits.md).
    let car = match samples.lock() {
        Ok(mut c) => std::mem::take(&mut *c),
        Err(_) => return,
    };
    let n = car.len();
    let car = &car[..];
    let q0 = FullCarParams::from_half(&s.vehicle).static_wheel_load();
    let Some((safety, flag)) =
        running_safety::assess(car, steady_rows(s, n), s.track.speed(), s.run.dt_s, q0)
    else {
        return;
    };
    match comfort_along_car(s, rows, car) {
        Ok(places) => {
            summary.full_car = Some(FullCarReport {
                running_safety: safety,
                comfort_along_car: places,
            });
            summary.flags.running_safety = Some(flag);
        }
        Err(e) => {
            summary.analysis_skipped = Some(format!("comfort along the car not computed: {e}"))
        }
    }
}

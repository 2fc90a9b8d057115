//! The whole car's part of a run (`vehicle.model = "full"`): an observer assesses the plant's
//! `car` values as they arrive (running safety, [`running_safety::Stream`]) and keeps the
//! body's lateral acceleration at three places for the comfort along the car, in a file
//! beside the run's rows when they are written (read back with them after the run, then
//! removed) or in memory with rows kept in memory. After the run's analysis they give
//! `summary.json`'s `full_car.running_safety` and `flags.running_safety`, and the comfort over
//! each bogie and at the centre (`full_car.comfort_along_car`). What is held does not grow with
//! the run (docs/limits.md).

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use tiltsim_assessment::comfort::LateralAcceleration;
use tiltsim_assessment::running_safety::{self, CarPlace, FullCarReport, CAR_VALUES};
use tiltsim_formats::table::Rows;
use tiltsim_master::engine::observe::{Observer, Start, Tick};
use tiltsim_master::engine::Summary;
use tiltsim_scenario::scenario::Scenario;
use vehicle_model::full_car::FullCarParams;

/// The places along the body the comfort is given at, in the order of `FromPlant::car`.
const PLACES: [&str; 3] = ["leading bogie", "centre", "trailing bogie"];

/// The body's lateral acceleration at the three places of one row (m/s²).
type Along = [f64; PLACES.len()];

/// Name of the file of the accelerations along the car, in the run's directory during the
/// run and its analysis.
pub const SPILL_FILE: &str = ".full_car_accelerations.bin";

/// Where the accelerations along the car are kept until the analysis.
enum Accelerations {
    /// In memory (the run's rows are kept in memory too).
    Kept(Vec<Along>),
    /// Little-endian f64 triples, one per row, in `path`; the first write error ends it.
    Spilled {
        path: PathBuf,
        file: Option<BufWriter<File>>,
        error: Option<String>,
    },
}

impl Accelerations {
    fn push(&mut self, a: Along) {
        match self {
            Accelerations::Kept(v) => v.push(a),
            Accelerations::Spilled { path, file, error } => {
                let Some(f) = file else { return };
                let bytes: Vec<u8> = a.iter().flat_map(|x| x.to_le_bytes()).collect();
                if let Err(e) = f.write_all(&bytes) {
                    *error = Some(format!("{}: {e}", path.display()));
                    *file = None;
                }
            }
        }
    }
}

impl Drop for Accelerations {
    fn drop(&mut self) {
        if let Accelerations::Spilled { path, file, .. } = self {
            file.take();
            let _ = std::fs::remove_file(path);
        }
    }
}

/// What the observer keeps of the whole car.
pub struct CarStream {
    safety: running_safety::Stream,
    along: Accelerations,
}

impl CarStream {
    fn push(&mut self, car: &[f64; CAR_VALUES]) {
        self.safety.push(car);
        self.along
            .push(std::array::from_fn(|i| car[CAR_VALUES - PLACES.len() + i]));
    }
    /// Values the running-safety assessment holds (its windows and the steady curve's
    /// samples): bounded whatever the run's length.
    pub fn held(&self) -> usize {
        self.safety.held()
    }
}

/// The handle the observer's state is read through after the run.
pub type CarSamples = Arc<Mutex<CarStream>>;

/// Assesses the plant's `car` values as they arrive, one per row of `timeseries.csv`.
pub struct CarObserver {
    stream: CarSamples,
}

impl CarObserver {
    /// An observer of a run of `s` and the handle its state is read through after the run;
    /// the accelerations along the car go to a file in `spill_dir` when given, else to memory.
    pub fn new(s: &Scenario, spill_dir: Option<&Path>) -> std::io::Result<(Self, CarSamples)> {
        let q0 = FullCarParams::from_half(&s.vehicle).static_wheel_load();
        let along = match spill_dir {
            Some(dir) => {
                let path = dir.join(SPILL_FILE);
                Accelerations::Spilled {
                    file: Some(BufWriter::new(File::create(&path)?)),
                    path,
                    error: None,
                }
            }
            None => Accelerations::Kept(Vec::new()),
        };
        let stream = Arc::new(Mutex::new(CarStream {
            safety: running_safety::Stream::new(steady_rows(s), s.track.speed(), s.run.dt_s, q0),
            along,
        }));
        Ok((
            CarObserver {
                stream: stream.clone(),
            },
            stream,
        ))
    }
    fn push(&self, car: &[f64; CAR_VALUES]) {
        if let Ok(mut s) = self.stream.lock() {
            s.push(car);
        }
    }
}

impl Observer for CarObserver {
    fn name(&self) -> &str {
        "full_car"
    }
    fn start(&mut self, start: &Start<'_>) -> std::io::Result<()> {
        self.push(&start.plant.car);
        Ok(())
    }
    fn tick(&mut self, tick: &Tick<'_>) -> std::io::Result<()> {
        self.push(&tick.plant.car);
        Ok(())
    }
}

/// The rows of the steady curve: the body's centre between the end of the entry transition
/// and the start of the exit one (rows past the run's end are never handed over).
pub fn steady_rows(s: &Scenario) -> std::ops::Range<usize> {
    let t = &s.track;
    let ds = s.track.speed() * s.run.dt_s;
    let start = t.straight_before_m + t.transition_m;
    let k0 = (start / ds).ceil() as usize;
    let k1 = ((start + t.curve_m) / ds).floor() as usize + 1;
    k0..k1.max(k0)
}

/// Comfort at each place: the run's samples for comfort (roll speed, references, deflection:
/// the run's own) with the passenger lateral acceleration, in both forms, the body's at that
/// place, which is what an accelerometer there measures (so the P_CT and the ride's N_MV both
/// take it).
fn comfort_along_car(
    s: &Scenario,
    rows: Rows<'_>,
    along: &mut dyn FnMut(u64) -> std::io::Result<Option<Along>>,
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
    let mut failed = None;
    tiltsim_report::analysis::scan(s, rows, |r, x| match along(r.step) {
        Ok(Some(c)) => {
            for (a, acc) in at.iter_mut().zip(c) {
                a.push(&tiltsim_assessment::comfort::Sample {
                    lat_acc: acc,
                    lat_acc_other: acc,
                    ..*x
                });
            }
        }
        Ok(None) => {}
        Err(e) => {
            failed.get_or_insert(e);
        }
    })?;
    if let Some(e) = failed {
        return Err(e);
    }
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

/// Reads the accelerations along the car of row `step`, rows asked for in increasing order
/// (None past the last).
struct SpillReader {
    file: BufReader<File>,
    next: u64,
}

impl SpillReader {
    fn at(&mut self, step: u64) -> std::io::Result<Option<Along>> {
        let mut buf = [0u8; 8 * PLACES.len()];
        while self.next <= step {
            match self.file.read_exact(&mut buf) {
                Ok(()) => self.next += 1,
                Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
                Err(e) => return Err(e),
            }
        }
        if self.next != step + 1 {
            return Ok(None);
        }
        Ok(Some(std::array::from_fn(|i| {
            f64::from_le_bytes(buf[8 * i..8 * i + 8].try_into().unwrap_or_default())
        })))
    }
}

/// The comfort along the car from the accelerations kept during the run and the run's rows.
fn comfort_from(
    s: &Scenario,
    rows: Rows<'_>,
    along: &mut Accelerations,
) -> Result<Vec<CarPlace>, String> {
    match along {
        Accelerations::Kept(v) => {
            comfort_along_car(s, rows, &mut |k| Ok(v.get(k as usize).copied()))
                .map_err(|e| e.to_string())
        }
        Accelerations::Spilled { path, file, error } => {
            if let Some(e) = error {
                return Err(format!("cannot write {e}"));
            }
            let flushed = file
                .take()
                .map(|f| f.into_inner().map_err(|e| e.into_error()));
            if let Some(Err(e)) = flushed {
                return Err(format!("cannot write {}: {e}", path.display()));
            }
            let file = File::open(&*path).map_err(|e| format!("{}: {e}", path.display()))?;
            let mut r = SpillReader {
                file: BufReader::new(file),
                next: 0,
            };
            comfort_along_car(s, rows, &mut |k| r.at(k)).map_err(|e| e.to_string())
        }
    }
}

/// Fills the summary's whole-car part from the observer's state and the run's rows (on
/// disk, or `rows` when kept in memory); a note in `analysis_skipped` when they cannot be
/// read. The accelerations' file is removed.
pub fn assess(s: &Scenario, summary: &mut Summary, samples: &CarSamples, rows: Rows<'_>) {
    let Ok(mut car) = samples.lock() else {
        return;
    };
    let Some((safety, flag)) = car.safety.finish() else {
        return;
    };
    match comfort_from(s, rows, &mut car.along) {
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
    // Removes the file now rather than when the last handle goes.
    car.along = Accelerations::Kept(Vec::new());
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant_proc::{Plant, PlantSettings};
    use tiltsim_protocol::msg::ToPlant;
    use tiltsim_protocol::Participant;

    /// The whole car on the default track (straight, transition, curve, transition,
    /// straight) with irregularity, its tilt bar swept by a slow sine: the plant's `car`
    /// values of every row, as a run hands them to the observer.
    fn record(s: &Scenario) -> Vec<[f64; CAR_VALUES]> {
        let mut plant = Plant::new(&PlantSettings {
            vehicle: s.vehicle.clone(),
            track: s.track.clone(),
            sensor: s.sensor.clone(),
            dt_s: s.run.dt_s,
            seed: s.run.seed,
        });
        let mut car = vec![plant.initial_output().car];
        for k in 0..s.steps() {
            let t = k as f64 * s.run.dt_s;
            let out = plant.step(&ToPlant {
                delta_a: 0.04 * (0.7 * t).sin(),
                ..Default::default()
            });
            car.push(out.car);
        }
        car
    }

    fn full_car() -> Scenario {
        Scenario::parse(
            "name = \"whole car\"\n[vehicle]\nmodel = \"full\"\n",
            Path::new("whole-car.toml"),
        )
        .unwrap()
    }

    /// The streamed assessment a run makes gives the very values (bit for bit: the same
    /// sums in the same order, exact medians) of the whole-record one on the same record,
    /// and holds only its windows and the steady curve's samples.
    #[test]
    fn the_streamed_running_safety_is_the_whole_record_one() {
        let s = full_car();
        let car = record(&s);
        let q0 = FullCarParams::from_half(&s.vehicle).static_wheel_load();
        let steady = steady_rows(&s);
        assert!(!steady.is_empty() && steady.end < car.len(), "{steady:?}");
        let batch = running_safety::assess(
            &car,
            steady.start.min(car.len())..steady.end.min(car.len()),
            s.track.speed(),
            s.run.dt_s,
            q0,
        )
        .unwrap();
        let mut stream =
            running_safety::Stream::new(steady.clone(), s.track.speed(), s.run.dt_s, q0);
        for c in &car {
            stream.push(c);
        }
        let streamed = stream.finish().unwrap();
        assert_eq!(format!("{streamed:?}"), format!("{batch:?}"));
        // Both quasi-static values present, the curve's forces not zero.
        assert_eq!(streamed.0.len(), 5);
        assert!(streamed.0.iter().all(|v| v.value > 0.0), "{streamed:?}");
        // Twelve windows of 2 m, and eight values per steady-curve row.
        let n = (2.0 / (s.track.speed() * s.run.dt_s)).round() as usize;
        assert_eq!(stream.held(), 12 * n + 8 * steady.len());
        // An eighth of the values the whole record has (23 a row) on this short track, the
        // curve a third of it; none of it grows with the run (below).
        assert!(
            stream.held() < car.len() * CAR_VALUES / 5,
            "{} of {}",
            stream.held(),
            car.len() * CAR_VALUES
        );
    }

    /// What the assessment holds is set by the window and the steady curve: a record ten
    /// times as long (the car running on past the track) holds the same count of values.
    #[test]
    fn what_is_held_does_not_grow_with_the_run() {
        let s = full_car();
        let car = record(&s);
        let q0 = FullCarParams::from_half(&s.vehicle).static_wheel_load();
        let held = |repeats: usize| {
            let mut stream =
                running_safety::Stream::new(steady_rows(&s), s.track.speed(), s.run.dt_s, q0);
            for c in (0..repeats).flat_map(|_| &car) {
                stream.push(c);
            }
            (stream.len(), stream.held())
        };
        let (one, held_one) = held(1);
        let (ten, held_ten) = held(10);
        assert_eq!(ten, 10 * one);
        assert_eq!(held_ten, held_one);
    }
}

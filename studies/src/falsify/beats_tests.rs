//! Better than random, shown: on the paper's LQG and MPC over the first 6 s (the straight and
//! the whole entry transition), with the bounds of docs/results.md's two worst-case tables,
//! the search's worst over 3 seeds is at least the worst of as many histories drawn by the
//! generator written apart from the search (`reach_tests::generate`: piecewise delays rising
//! and falling within the jitter bound, bursts, the budgets spent as one outage or many) and
//! at least every obvious adversary's.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use rand::SeedableRng as _;
use rand_chacha::ChaCha8Rng;

use super::bounds::Bounds;
use super::history::{History, Layout};
use super::search::{evaluate, Exec, Method, Phase, Spec};
use super::tests::shipped;
use super::Objective;

/// Evaluations of the search, and draws of the independent generator.
const BUDGET: usize = 60;

fn bounds(name: &str) -> Bounds {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../docs")
        .join(name);
    Bounds::read(&path).unwrap()
}

#[test]
fn the_search_beats_an_independent_sampler_and_the_adversaries() {
    let interrupt = Arc::new(AtomicBool::new(false));
    let dir = std::env::temp_dir().join(format!("tiltsim-beats-{}", std::process::id()));
    let mut report = Vec::new();
    for scen in ["paper-lqg.toml", "paper-mpc.toml"] {
        let mut s = shipped(scen, 6.0);
        super::prepare(&mut s, scen).unwrap();
        for file in ["falsify-command-bounds.toml", "falsify-links-bounds.toml"] {
            let b = bounds(file);
            let ticks = b.ticks(&s, file).unwrap();
            let layout = Layout::new(&s, &ticks);
            let objective = Objective::maximise("p_ct").unwrap();
            for seed in 1..=3u64 {
                let spec = Spec {
                    bounds: b,
                    bounds_from: file.into(),
                    objective: objective.clone(),
                    budget: BUDGET,
                    seed,
                    margin: None,
                };
                let out = dir.join(format!("{scen}-{file}-{seed}"));
                let ex = Exec {
                    out: out.clone(),
                    jobs: 2,
                    exe: Default::default(),
                    interrupt: interrupt.clone(),
                    done: None,
                };
                let f = super::run(&s, &spec, &ex).unwrap();
                let _ = std::fs::remove_dir_all(&out);
                let best = |keep: &dyn Fn(&super::search::Eval) -> bool| {
                    f.evals
                        .iter()
                        .filter(|e| e.method == Method::CmaEs && keep(e))
                        .map(|e| e.objective)
                        .fold(f64::NEG_INFINITY, f64::max)
                };
                let search = best(&|_| true);
                let adversaries = best(&|e| e.phase == Phase::Adversary);
                let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
                let drawn = (0..BUDGET)
                    .map(|_| {
                        let h: History = std::array::from_fn(|i| {
                            let (l, b, _) = &layout.links[i];
                            super::reach_tests::generate(&mut rng, l, b)
                        });
                        let v =
                            evaluate(&s, &layout, &ticks, &objective, &h, out.clone(), &interrupt);
                        assert!(v.error.is_empty(), "{scen} {file}: {}", v.error);
                        v.objective
                    })
                    .fold(f64::NEG_INFINITY, f64::max);
                report.push(format!(
                    "{scen} {file} seed {seed}: search {search:.4}, adversaries {adversaries:.4}, independent sampler {drawn:.4}"
                ));
                assert!(
                    search >= drawn && search >= adversaries,
                    "{}",
                    report.join("\n")
                );
            }
        }
    }
    eprintln!("{}", report.join("\n"));
}

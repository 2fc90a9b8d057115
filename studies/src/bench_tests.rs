//! Tests of the bench report: withheld ratios and which rows are set beside which floor.
use super::*;
use cosim::ipc::placement::Reason;

#[test]
fn ratios_are_withheld_when_the_rounds_spread() {
    let walls = |ipc: Vec<f64>| WallRounds {
        in_process_s: vec![1.0, 1.1, 1.05],
        ipc_gauss_seidel_s: ipc,
        ipc_jacobi_s: vec![1.2, 1.25, 1.3],
        ..WallRounds::default()
    };
    // Rounds within a tenth of each other: drawn.
    assert_eq!(withheld(&walls(vec![1.5, 1.6, 1.55])), None);
    // One round 1.5 s, the next 30 s (a build started beside it): withheld, named.
    let why = withheld(&walls(vec![1.5, 30.0, 1.6])).unwrap();
    assert!(
        why.contains("IPC gauss-seidel") && why.contains("1781 %"),
        "{why}"
    );
    // Fewer than three rounds: no spread to judge.
    assert_eq!(spread(&[1.0, 9.0]), None);
    assert_eq!(withheld(&walls(vec![1.5, 9.0])), None);
    assert_eq!(spread(&[1.0, 1.5, 2.0]), Some(1.0 / 1.5));
}

/// A row of `master` over `transport` with `wait`, placed for `reason`, overhead p50 10 µs.
fn row(transport: Transport, master: Master, wait: WaitStrategy, reason: Option<Reason>) -> Config {
    Config {
        transport: transport.name(),
        master: master.name(),
        wait: wait.name(),
        realtime: false,
        placement: reason,
        ticks: 100,
        overhead_p50_us: 10.0,
        overhead_p99_us: 20.0,
        plant_round_trip_p50_us: 3.0,
        plant_round_trip_p99_us: 6.0,
        wall_s: 0.1,
        cpu_s: 0.2,
        exchange_floor_us: None,
        exchange_floor_worst_us: None,
        overhead_over_floor: None,
        rounds: vec![Round {
            overhead_p50_us: 10.0,
            placement: reason,
            overhead_over_floor: None,
        }],
    }
}

fn p50(p50: f64) -> cosim::stats::Percentiles {
    cosim::stats::Percentiles {
        n: 10,
        p50,
        p99: 2.0 * p50,
        max: 3.0 * p50,
        mean: p50,
    }
}

#[test]
fn only_adaptive_rows_with_a_pair_of_cpus_are_set_beside_their_masters_floor() {
    let floors = ExchangeFloors {
        every: vec![1, 1, 1],
        ticks: 10,
        sets_per_round: 3,
        in_turn_sets_us: vec![p50(8.0), p50(5.0), p50(6.0)],
        all_at_once_sets_us: vec![p50(4.0), p50(2.5), p50(3.0)],
    };
    // The floor of a pattern is its best set's p50, beside its worst.
    assert_eq!(floors.in_turn_us(), (5.0, 8.0));
    assert_eq!(floors.all_at_once_us(), (2.5, 4.0));
    assert_eq!(floors.rounds(), 1);
    use Master::*;
    use WaitStrategy::*;
    let pair = Some(Reason::FreePair);
    let mut r = run_report(vec![
        row(Transport::InProcess, GaussSeidel, Adaptive, None),
        row(Transport::Ipc, GaussSeidel, Adaptive, pair),
        row(Transport::Ipc, Jacobi, Adaptive, pair),
        row(
            Transport::Ipc,
            GaussSeidel,
            Adaptive,
            Some(Reason::Contended),
        ),
        row(Transport::Ipc, GaussSeidel, Sleep, pair),
        row(Transport::Ipc, Jacobi, Spin, pair),
    ]);
    r.set_exchange_floors(floors);
    let got: Vec<_> = r
        .configs
        .iter()
        .map(|c| {
            (
                c.exchange_floor_us,
                c.exchange_floor_worst_us,
                c.overhead_over_floor,
            )
        })
        .collect();
    assert_eq!(
        got,
        [
            (None, None, None),
            (Some(5.0), Some(8.0), Some(2.0)),
            (Some(2.5), Some(4.0), Some(4.0)),
            (None, None, None),
            (None, None, None),
            (None, None, None),
        ]
    );
    assert!(r.exchange_floors.is_some());
}

/// The machine's latency between CPUs changes over minutes (docs/performance.md): a round run
/// while it was high is set beside the floor measured right after it, not beside the best set
/// of another round, and the row's ratio is the median of its rounds'.
#[test]
fn each_round_is_set_beside_the_floor_measured_right_after_it() {
    let floors = ExchangeFloors {
        every: vec![1, 1, 1],
        ticks: 10,
        sets_per_round: 2,
        // Round 1 fast (best 5), round 2 slow (best 7), round 3 fast (best 4.5; 9 in the
        // slow rotation).
        in_turn_sets_us: vec![p50(5.0), p50(5.5), p50(7.0), p50(7.5), p50(9.0), p50(4.5)],
        all_at_once_sets_us: vec![p50(5.0), p50(5.0), p50(7.0), p50(6.8), p50(5.0), p50(5.2)],
    };
    assert_eq!(floors.rounds(), 3);
    assert_eq!(floors.round_best_us("gauss-seidel", 1), Some(7.0));
    assert_eq!(floors.round_best_us("jacobi", 1), Some(6.8));
    assert_eq!(floors.round_best_us("jacobi", 3), None);
    let round = |overhead: f64, placement| Round {
        overhead_p50_us: overhead,
        placement,
        overhead_over_floor: None,
    };
    let pair = Some(Reason::FreePair);
    let mut gs = row(
        Transport::Ipc,
        Master::GaussSeidel,
        WaitStrategy::Adaptive,
        pair,
    );
    gs.rounds = vec![round(5.0, pair), round(7.7, pair), round(4.95, pair)];
    let mut jacobi = row(Transport::Ipc, Master::Jacobi, WaitStrategy::Adaptive, pair);
    // Its second round left to the kernel among other work: no ratio for it.
    jacobi.rounds = vec![
        round(5.5, pair),
        round(30.0, Some(Reason::Contended)),
        round(4.0, pair),
    ];
    let mut r = run_report(vec![gs, jacobi]);
    r.set_exchange_floors(floors);
    let each = |c: &Config| {
        c.rounds
            .iter()
            .map(|x| x.overhead_over_floor.map(|v| (v * 1000.0).round() / 1000.0))
            .collect::<Vec<_>>()
    };
    // Under the table, each round's overhead, its floor and their ratio.
    let table = crate::bench_table::table(&r);
    assert!(
        table.contains(
            "ipc gauss-seidel, each round: 5.00 / 5.00 µs = 1.00; 7.70 / 7.00 µs = 1.10; \
             4.95 / 4.50 µs = 1.10"
        ),
        "{table}"
    );
    assert!(
        table.contains("ipc jacobi, each round: 5.50 / 5.00 µs = 1.10; 30.00 / 6.80 µs = -;"),
        "{table}"
    );
    let (gs, jacobi) = (&r.configs[0], &r.configs[1]);
    assert_eq!(each(gs), [Some(1.0), Some(1.1), Some(1.1)]);
    // The median of 1.0, 1.1, 1.1 (against the best set of all rounds, 4.5 µs, the slow
    // round alone would read 1.71).
    assert!((gs.overhead_over_floor.unwrap() - 1.1).abs() < 1e-12);
    assert_eq!(
        (gs.exchange_floor_us, gs.exchange_floor_worst_us),
        (Some(4.5), Some(9.0))
    );
    assert_eq!(each(jacobi), [Some(1.1), None, Some(0.8)]);
    // Two rounds: the lower of the middle two.
    assert!((jacobi.overhead_over_floor.unwrap() - 0.8).abs() < 1e-12);
}

/// A report holding `configs` and nothing measured besides.
fn run_report(configs: Vec<Config>) -> Report {
    Report {
        scenario: "s".into(),
        duration_s: 1.0,
        cpus: 2,
        machine: Machine::this(),
        ipc_round_trip_floor_us: 3.0,
        configs,
        wall_in_process_s: 0.1,
        wall_ipc_s: 0.2,
        ipc_over_in_process: None,
        wall_ipc_jacobi_s: 0.2,
        jacobi_ipc_over_in_process: None,
        realtime: None,
        hogs: 0,
        ratio_withheld: None,
        load_average: LoadSpan {
            before: None,
            after: None,
        },
        wall_spread: [None; 3],
        wall_rounds: WallRounds::default(),
        machine_floors: None,
        exchange_floors: None,
    }
}

#[test]
fn the_real_time_runs_are_measured_and_compared_only_when_asked_for() {
    let names = |v: Vec<Plan>| v.iter().map(Plan::name).collect::<Vec<_>>();
    // Without --realtime: in-process, then six IPC rows, none under SCHED_FIFO.
    let plain = configurations(false);
    assert_eq!(plain.len(), 7);
    assert!(plain.iter().all(|p| !p.realtime));
    assert_eq!(
        names(compared(false)),
        [
            "in-process gauss-seidel adaptive",
            "ipc gauss-seidel adaptive",
            "ipc jacobi adaptive"
        ]
    );
    // With it: the two adaptive IPC rows again under SCHED_FIFO, measured and compared.
    let rt = configurations(true);
    assert_eq!(
        names(rt[7..].to_vec()),
        [
            "ipc gauss-seidel adaptive realtime",
            "ipc jacobi adaptive realtime"
        ]
    );
    assert_eq!(compared(true).len(), 5);
    // Their rounds are kept apart from the ordinary ones, and judged for spread by name.
    let mut walls = WallRounds::default();
    for (p, w) in compared(true).into_iter().zip([1.0, 2.0, 3.0, 4.0, 5.0]) {
        walls.add(p, w);
    }
    assert_eq!(walls.ipc_gauss_seidel_s, [2.0]);
    assert_eq!(walls.ipc_gauss_seidel_realtime_s, [4.0]);
    assert_eq!(walls.ipc_jacobi_realtime_s, [5.0]);
    walls.ipc_jacobi_realtime_s = vec![1.0, 1.0, 9.0];
    let why = withheld(&walls).unwrap();
    assert!(why.starts_with("the IPC jacobi realtime rounds"), "{why}");
}

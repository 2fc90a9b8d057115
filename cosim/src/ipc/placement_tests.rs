use super::*;

#[test]
fn a_run_pins_to_two_cpus_that_no_run_claims_and_no_work_keeps_busy() {
    let all: Vec<usize> = (0..8).collect();
    let p = choose(WaitStrategy::Adaptive, true, &all, &[0, 1], &[2]);
    assert_eq!(p.reason, Reason::FreePair);
    assert_eq!(p.orchestrator_cpu, Some(3));
    assert_eq!(p.participant_cpus, vec![4]);
    assert_eq!(p.shared_participant_cpu(), Some(4));
    assert_eq!(p.wait, WaitStrategy::Adaptive);
}

#[test]
fn with_fewer_than_two_free_cpus_nothing_is_pinned_and_waiters_nap() {
    let p = choose(WaitStrategy::Adaptive, true, &[0, 1], &[0, 1], &[]);
    assert_eq!(p.reason, Reason::Contended);
    assert!(!p.pinned());
    assert_eq!(p.wait, WaitStrategy::Paced);
    // Two CPU hogs beside a run on two CPUs: the same.
    let p = choose(WaitStrategy::Adaptive, true, &[0, 1], &[], &[0, 1]);
    assert_eq!(p.reason, Reason::Contended);
    assert_eq!(p.wait, WaitStrategy::Paced);
}

#[test]
fn spin_gets_a_cpu_for_each_process_or_falls_back() {
    let all: Vec<usize> = (0..8).collect();
    let p = choose(WaitStrategy::Spin, true, &all, &[0, 1], &[]);
    assert_eq!(p.reason, Reason::FreeCpuEach);
    assert_eq!(p.orchestrator_cpu, Some(2));
    assert_eq!(p.participant_cpus, vec![3, 4, 5]);
    assert_eq!(p.shared_participant_cpu(), None);
    assert_eq!(p.wait, WaitStrategy::Spin);
    // Two CPUs: pinned as a pair, waiting as adaptive does.
    let p = choose(WaitStrategy::Spin, true, &[0, 1], &[], &[]);
    assert_eq!(p.reason, Reason::FreePair);
    assert_eq!(p.wait, WaitStrategy::Adaptive);
    // Unpinned on two CPUs: the same fallback.
    let p = choose(WaitStrategy::Spin, false, &[0, 1], &[], &[]);
    assert_eq!(p.reason, Reason::NotAsked);
    assert_eq!(p.wait, WaitStrategy::Adaptive);
}

/// A directory of its own under the system's temporary directory, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let d = std::env::temp_dir().join(prefix(name));
        std::fs::create_dir_all(&d).expect("temporary directory");
        TempDir(d)
    }
    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A prefix unique to this test process and `name`.
fn prefix(name: &str) -> String {
    format!("tiltsim_test_placement_{}_{name}_", std::process::id())
}

#[test]
fn two_runs_claim_disjoint_cpus_and_a_dropped_claim_is_released() {
    let dir = TempDir::new("claims");
    let a = write_claim(dir.path(), &prefix("a"), &[0, 1]).expect("claim a");
    let b = write_claim(dir.path(), &prefix("b"), &[2, 3]).expect("claim b");
    assert_eq!(live_claims(dir.path()), vec![0, 1, 2, 3]);
    // A second run chooses around the first's claim.
    let p = choose(
        WaitStrategy::Adaptive,
        true,
        &[0, 1, 2, 3, 4, 5],
        &live_claims(dir.path()),
        &[],
    );
    assert_eq!(p.orchestrator_cpu, Some(4));
    assert_eq!(p.participant_cpus, vec![5]);
    drop(a);
    assert_eq!(live_claims(dir.path()), vec![2, 3]);
    drop(b);
    assert!(live_claims(dir.path()).is_empty());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "files removed"
    );
}

#[test]
fn a_claim_whose_owner_is_gone_does_not_count() {
    // The lock of a killed run is released by the kernel; its file stays until the run's files
    // are cleaned. Written without a lock, it stands for such a file.
    let dir = TempDir::new("dead");
    std::fs::write(
        dir.path().join(format!("{}{CLAIM_FILE}", prefix("dead"))),
        "0\n1\n",
    )
    .unwrap();
    assert!(live_claims(dir.path()).is_empty());
}

#[test]
fn an_idle_cpu_is_not_busy() {
    // CPU 0 idle 9 of 10 ticks, CPU 1 idle 1 of 10, CPU 2 no ticks counted.
    let before = [(0, 100, 1000), (1, 100, 1000), (2, 5, 50)];
    let after = [(0, 109, 1010), (1, 101, 1010), (2, 5, 50)];
    assert_eq!(busy_between(&[0, 1, 2], &before, &after), vec![1]);
}

#[test]
fn a_reason_is_named_as_summary_json_names_it() {
    use Reason::*;
    for r in [
        FreePair,
        FreeCpuEach,
        NotAsked,
        TooFewCpus,
        Contended,
        RegistryUnavailable,
    ] {
        assert_eq!(serde_json::to_value(r).unwrap(), r.name());
    }
}

//! docs/results.md quotes what the build computes: its headline comfort cells, its drive
//! cells and the rankings its prose states are those of a fresh comparison of the same
//! scenarios (every one of them deterministic), so a change that moves a number fails here
//! until `scripts/results.sh` has regenerated the document.

use std::collections::HashMap;

use tiltsim_suite::{root, run, scenario, temp_dir};

/// The cells of a markdown table: the row whose first cell is `first`, by column header.
fn table_row(md: &str, header_start: &str, first: &str) -> HashMap<String, String> {
    let lines: Vec<&str> = md.lines().collect();
    let cells = |l: &str| -> Vec<String> {
        l.trim()
            .trim_matches('|')
            .split('|')
            .map(|c| c.trim().to_string())
            .collect()
    };
    let h = lines
        .iter()
        .position(|l| l.starts_with(header_start))
        .unwrap_or_else(|| panic!("no table whose header starts {header_start:?}"));
    let heads = cells(lines[h]);
    let row = lines[h + 2..]
        .iter()
        .take_while(|l| l.starts_with('|'))
        .map(|l| cells(l))
        .find(|c| c[0] == first)
        .unwrap_or_else(|| panic!("no row {first:?} under {header_start:?}"));
    heads.into_iter().zip(row).collect()
}

/// The column of run `name` among `row`'s headers (`LABEL [name]`).
fn cell<'a>(row: &'a HashMap<String, String>, name: &str) -> &'a str {
    row.iter()
        .find(|(h, _)| h.ends_with(&format!("[{name}]")))
        .map(|(_, v)| v.as_str())
        .unwrap_or_else(|| panic!("no column for {name}"))
}

#[test]
fn the_numbers_docs_results_quotes_are_those_the_build_computes() {
    let doc = std::fs::read_to_string(root().join("docs/results.md")).unwrap();
    let dir = temp_dir("results-doc");
    let runs = [
        "pi-drive",
        "paper-lqg",
        "paper-mpc",
        "paper-mpc-hold",
        "paper-pi",
    ];
    let files: Vec<String> = runs
        .iter()
        .map(|r| scenario(&format!("{r}.toml")).display().to_string())
        .collect();
    let mut args = vec!["compare"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--out", dir.to_str().unwrap(), "--transport", "in-process"]);
    let (code, _, err) = run(&args);
    assert_eq!(code, 0, "{err}");
    let fresh = std::fs::read_to_string(dir.join("table.md")).unwrap();

    // Comfort: the standard's P_CT, the paper's form and the peak lateral acceleration, cell
    // for cell (the paper's value and our difference included where the cell has them).
    for metric in [
        "P_CT standing, EN 12299 (per transition, 0.3 Hz filtered) (%)",
        "P_CT seated, EN 12299 (per transition, 0.3 Hz filtered) (%)",
        "P_CT standing, the paper's Table 4 form: whole-run peaks (%)",
        "Lateral acceleration peak (%g)",
    ] {
        let want = table_row(&fresh, "| metric |", metric);
        let have = table_row(&doc, "| metric |", metric);
        for r in runs {
            assert_eq!(
                cell(&have, r),
                cell(&want, r),
                "docs/results.md, {metric}, {r}: regenerate it with scripts/results.sh"
            );
        }
    }
    // The drive: peaks of torque, phase current and power, and the chopper's energy (the
    // wall-clock columns marked † are not compared).
    for r in runs {
        let want = table_row(&fresh, "| run | status |", r);
        let have = table_row(&doc, "| run | status |", r);
        for col in [
            "torque peak (N·m)",
            "phase current peak (A)",
            "motoring / braking power peak (kW)",
            "chopper (kJ)",
        ] {
            assert_eq!(
                have[col], want[col],
                "docs/results.md, {r}, {col}: regenerate it with scripts/results.sh"
            );
        }
    }
    // The prose states both rankings with one decimal: the build's values, in that order.
    let value = |metric: &str, r: &str| -> f64 {
        let row = table_row(&fresh, "| metric |", metric);
        let text = cell(&row, r).trim_start_matches("⚠ ");
        text.split_whitespace().next().unwrap().parse().unwrap()
    };
    let en = "P_CT standing, EN 12299 (per transition, 0.3 Hz filtered) (%)";
    let paper = "P_CT standing, the paper's Table 4 form: whole-run peaks (%)";
    let standard = format!(
        "MPC-KF {:.1} < PI-drive {:.1} < LQG {:.1} %",
        value(en, "paper-mpc"),
        value(en, "pi-drive"),
        value(en, "paper-lqg")
    );
    let reversed = format!(
        "LQG {:.1} < PI-drive {:.1} < MPC-KF {:.1} %",
        value(paper, "paper-lqg"),
        value(paper, "pi-drive"),
        value(paper, "paper-mpc")
    );
    let flat = doc.split_whitespace().collect::<Vec<_>>().join(" ");
    for sentence in [standard, reversed] {
        assert!(
            flat.contains(&sentence),
            "docs/results.md does not state {sentence:?}: the prose in docs/results.in.md \
             quotes other values than the build computes"
        );
    }
}

/// docs/results.md's whole line: each vehicle's line summary and its P_CT under each reading
/// of EN 12299 are those a fresh `tiltsim route` of the same line and scenarios computes
/// (deterministic: every segment's seed is its own).
#[test]
fn the_whole_line_docs_results_quotes_is_the_one_the_build_computes() {
    let doc = std::fs::read_to_string(root().join("docs/results.md")).unwrap();
    let dir = temp_dir("results-doc-route");
    let line = root().join("routes/winding-valley.csv");
    let names = ["line-passive", "line-pi-drive", "line-lqg", "line-mpc"];
    let files: Vec<String> = names
        .iter()
        .map(|r| scenario(&format!("{r}.toml")).display().to_string())
        .collect();
    let mut args = vec!["route", line.to_str().unwrap()];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--out", dir.to_str().unwrap(), "-q"]);
    let (code, _, err) = run(&args);
    assert_eq!(code, 0, "{err}");
    let fresh = std::fs::read_to_string(dir.join("route.md")).unwrap();
    for name in names {
        for header in [
            "| variant | controller |",
            "| variant | 0.3 Hz (EN 12299) |",
        ] {
            assert_eq!(
                table_row(&doc, header, name),
                table_row(&fresh, header, name),
                "docs/results.md, the whole line, {name}: regenerate it with scripts/results.sh"
            );
        }
    }
    assert!(
        doc.contains(
            fresh
                .lines()
                .find(|l| l.starts_with("| tilting |"))
                .unwrap()
        ),
        "docs/results.md, the whole line's journey times: regenerate it with scripts/results.sh"
    );
}

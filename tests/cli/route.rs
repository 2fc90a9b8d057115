//! `tiltsim route`: a route file's errors, the same results for any number of parallel runs
//! and either transport, and a tilting train's time saved against its conventional profile.

use tiltsim_suite::{csv_table, root, run, scenario, temp_dir};

const LINE: &str = "# two curves between three straights
chainage_m,length_m,radius_m,cant_mm,transition_m,shape,vmax_conventional_kmh,vmax_tilting_kmh
0,3000,,,,,160,200
3000,700,1100,130,120,clothoid,160,200
3700,1500,,,,,160,200
5200,600,-800,150,140,bloss,130,150
5800,2500,,,,,160,200
";

fn read(p: &std::path::Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn a_bad_route_file_is_refused_naming_its_line_and_column() {
    let dir = temp_dir("route-bad");
    for (from, to, want) in [
        ("bloss", "spiral", "bad.csv:6: shape: `spiral`; expected clothoid, cosine or bloss"),
        ("3700,1500", "3710,1500", "bad.csv:5: chainage_m: 3710 does not continue the section of line 4, which ends at 3700 m"),
        ("1100,130", "1100,260", "bad.csv:4: cant_mm: 260 is out of range; expected 0 to 200 mm"),
        ("-800,150,140", "-800,150,400", "bad.csv:6: transition_m: two transitions of 400 m do not fit"),
    ] {
        let f = dir.join("bad.csv");
        std::fs::write(&f, LINE.replace(from, to)).unwrap();
        let out = dir.join("out");
        let (code, _, err) = run(&["route", f.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_eq!(code, 2, "{err}");
        assert!(err.contains(want), "{err}");
        assert!(!out.join("route.json").exists());
    }
}

#[test]
fn a_route_gives_the_same_bytes_for_any_jobs_and_either_transport() {
    let dir = temp_dir("route-transports");
    let f = dir.join("line.csv");
    std::fs::write(&f, LINE).unwrap();
    let s = scenario("tilting-pi-drive.toml");
    let go = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "route",
            f.to_str().unwrap(),
            s.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ];
        args.extend(extra);
        let (code, _, err) = run(&args);
        assert_eq!(code, 0, "{err}");
        out
    };
    let one = go("one", &["--jobs", "1"]);
    let two = go("two", &["--jobs", "2"]);
    let ipc = go("ipc", &["--jobs", "2", "--transport", "ipc"]);
    for file in [
        "transitions.csv",
        "straights.csv",
        "variants.csv",
        "profile.csv",
    ] {
        assert_eq!(
            read(&one.join(file)),
            read(&two.join(file)),
            "{file}: --jobs 1 and 2 differ"
        );
        assert_eq!(
            read(&two.join(file)),
            read(&ipc.join(file)),
            "{file}: in-process and IPC differ"
        );
    }
    // Four transitions, each with a P_CT, at the file's chainages.
    let t = csv_table(&String::from_utf8(read(&two.join("transitions.csv"))).unwrap());
    let col = |name: &str| t[0].iter().position(|h| h == name).unwrap();
    let chainages: Vec<&str> = t[1..]
        .iter()
        .map(|r| r[col("chainage_m")].as_str())
        .collect();
    assert_eq!(chainages, ["3000", "3580", "5200", "5660"]);
    for r in &t[1..] {
        let p: f64 = r[col("p_ct_standing_pct")].parse().unwrap();
        assert!(p > 0.0 && p < 100.0, "P_CT {p}");
    }
}

#[test]
fn the_shipped_lines_are_long_and_tilting_saves_time_on_them() {
    for (line, curves) in [("winding-valley", 36), ("upland-main", 32)] {
        let dir = temp_dir(&format!("route-{line}"));
        let f = root().join("routes").join(format!("{line}.csv"));
        let (code, out, err) = run(&["route", f.to_str().unwrap(), "--out", dir.to_str().unwrap()]);
        assert_eq!(code, 0, "{err}");
        assert!(out.contains(&format!("{curves} curves")), "{out}");
        let j: serde_json::Value =
            serde_json::from_str(&String::from_utf8(read(&dir.join("route.json"))).unwrap())
                .unwrap();
        let (c, t) = (
            j["journey"]["conventional_s"].as_f64().unwrap(),
            j["journey"]["tilting_s"].as_f64().unwrap(),
        );
        // The tilting profile is faster everywhere its limits are higher: a lower bound on the
        // saving is not asserted, only that it is a saving and that the conventional journey
        // is no faster than the line at its conventional line speed throughout.
        assert!(t < c, "{line}: tilting {t} s, conventional {c} s");
        let length = j["length_m"].as_f64().unwrap();
        let line_speed = if line == "winding-valley" {
            160.0
        } else {
            200.0
        } / 3.6;
        assert!(c > length / line_speed, "{line}: {c} s for {length} m");
    }
}

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

/// The whole car over a route (`[vehicle] model = "full"`): every segment reports its running
/// safety in `route.json`, `safety.csv` and `route.md`, flagged like comfort (the variant's
/// flags name `running safety` exactly when a segment's limit is exceeded). On each curve the
/// quasi-static lateral wheel force is at least the share of the car's uncompensated weight
/// one wheel must carry: the rails push the car inwards with M (V²/R − g θ) in all, over four
/// wheelsets, and a wheelset's ΣY is the sum of its two wheels' Y, so the most loaded wheel
/// carries at least an eighth, M = 8 Q0/g with Q0 from the track shift force's limit
/// α(10 + 2 Q0/3000) kN (α = 1). 10 % below it for the irregularity's spread of the median.
/// The half vehicle, with no wheelsets, writes none of it.
#[test]
fn a_route_run_with_the_whole_car_reports_running_safety_on_every_segment() {
    let dir = temp_dir("route-full-car");
    let f = dir.join("line.csv");
    std::fs::write(&f, LINE).unwrap();
    let text = std::fs::read_to_string(scenario("tilting-pi-drive.toml")).unwrap();
    let full = dir.join("full.toml");
    std::fs::write(&full, text + "\n[vehicle]\nmodel = \"full\"\n").unwrap();
    let go = |name: &str, s: &std::path::Path| {
        let out = dir.join(name);
        let (code, _, err) = run(&[
            "route",
            f.to_str().unwrap(),
            s.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ]);
        assert_eq!(code, 0, "{err}");
        out
    };
    let out = go("full", &full);
    let j: serde_json::Value =
        serde_json::from_str(&String::from_utf8(read(&out.join("route.json"))).unwrap()).unwrap();
    let v = &j["variants"][0];
    let rows = v["running_safety"].as_array().expect("running_safety");
    assert_eq!(rows.len() as u64, v["segments"].as_u64().unwrap());
    // The two curves of LINE: radius (m) and cant (mm).
    let curves = [(1100.0, 130.0), (800.0, 150.0)];
    let mut curve = 0;
    let mut raised = false;
    for r in rows {
        let values = r["values"].as_array().unwrap();
        let get = |q: &str| values.iter().find(|x| x["quantity"] == q);
        for x in values {
            let (value, limit) = (x["value"].as_f64().unwrap(), x["limit"].as_f64().unwrap());
            assert_eq!(x["exceeded"].as_bool().unwrap(), value > limit, "{x}");
        }
        raised |= r["flag"]["raised"].as_bool().unwrap();
        if !r["curve"].as_bool().unwrap() {
            continue;
        }
        let (radius, cant) = curves[curve];
        curve += 1;
        let speed = r["speed_kmh"].as_f64().unwrap() / 3.6;
        let limit = get("(SumY)_2m").unwrap()["limit"].as_f64().unwrap();
        let q0 = (limit / 1000.0 - 10.0) * 1500.0;
        let unbalanced = speed * speed / radius - 9.81 * (cant / 1500.0f64).asin();
        let least = q0 * unbalanced.abs() / 9.81;
        let y_qst = get("Y_qst").expect("Y_qst on a curve")["value"]
            .as_f64()
            .unwrap();
        assert!(
            y_qst > 0.9 * least,
            "curve {curve}: Y_qst {y_qst} N, at least {least} N"
        );
        assert!(get("Q_qst").is_some());
    }
    assert_eq!(curve, 2);
    let flags: Vec<&str> = v["flags"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert_eq!(flags.contains(&"running safety"), raised, "{flags:?}");
    let csv = csv_table(&String::from_utf8(read(&out.join("safety.csv"))).unwrap());
    assert_eq!(csv.len(), rows.len() + 1);
    assert!(String::from_utf8(read(&out.join("route.md")))
        .unwrap()
        .contains("running safety of the whole car"));
    let half = go("half", &scenario("tilting-pi-drive.toml"));
    let j: serde_json::Value =
        serde_json::from_str(&String::from_utf8(read(&half.join("route.json"))).unwrap()).unwrap();
    assert!(j["variants"][0].get("running_safety").is_none());
    assert!(!half.join("safety.csv").exists());
}

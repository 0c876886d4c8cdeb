//! `waam bench scale --generate`: every family's generated part passes `waam check` with
//! its witness plan, and the summary names each family with its solve rate.

use crate::common::run::waam;

#[test]
fn generated_parts_pass_waam_check_with_their_witness() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("bench.json");
    let out = waam()
        .args([
            "bench",
            "scale",
            "--generate",
            "1",
            "--seed",
            "11",
            "--blocks",
            "400",
        ])
        .args(["--timeout", "30", "--threads", "2", "--out"])
        .arg(dir.path())
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let families = ["tube", "box", "double-tube", "l-wall", "t-wall", "cup"];
    for family in families {
        let name = format!("{family}-400-s11");
        let part = dir.path().join(format!("{name}.yaml"));
        let plan = dir.path().join(format!("{name}.witness.yaml"));
        let check = waam().arg("check").arg(&part).arg(&plan).output().unwrap();
        let text = String::from_utf8_lossy(&check.stdout);
        assert_eq!(check.status.code(), Some(0), "{name}: {text}");
        assert!(text.contains("FEASIBLE"), "{name}: {text}");
    }
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let summary = v["summary"].as_array().unwrap();
    let named: Vec<&str> = summary
        .iter()
        .map(|s| s["family"].as_str().unwrap())
        .collect();
    assert_eq!(named, families);
    assert_eq!(v["runs"].as_array().unwrap().len(), 6);
    for s in summary {
        assert_eq!(s["parts"], 1);
    }

    // The folder `--out` wrote, timed as a folder on the threads asked for: the six parts,
    // not their witness plans.
    let folder_json = dir.path().join("folder.json");
    let out = waam()
        .args([
            "bench",
            "scale",
            "--timeout",
            "30",
            "--threads",
            "1",
            "--json",
        ])
        .arg(&folder_json)
        .arg(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}");
    assert!(!stdout.contains("skipped"), "{stdout}");
    let rows: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&folder_json).unwrap()).unwrap();
    let rows = rows.as_array().unwrap();
    let files: Vec<&str> = rows.iter().map(|r| r["file"].as_str().unwrap()).collect();
    let mut expected: Vec<String> = families
        .iter()
        .map(|f| format!("{f}-400-s11.yaml"))
        .collect();
    expected.sort();
    assert_eq!(files, expected);
    for row in rows {
        assert_eq!(row["first"]["threads"], 1, "{row}");
        assert_eq!(row["first"]["checked"], true, "{row}");
        // One thread: no race, so no racer is named.
        assert!(row["first"]["racer"].is_null(), "{row}");
    }
}

#[test]
fn an_unknown_family_is_refused_by_name() {
    let out = waam()
        .args(["bench", "scale", "--generate", "1", "--family", "pipe"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("\"pipe\""));
}

/// `--best` times a folder's best plans; with --generate it is refused (exit 2, both flags
/// named) rather than silently left out.
#[test]
fn best_with_generate_is_refused() {
    let out = waam()
        .args(["bench", "scale", "--generate", "1", "--best"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--best") && stderr.contains("--generate"),
        "{stderr}"
    );
}

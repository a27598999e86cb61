//! `interpd plan raster` refuses flags that would write a wrong program
//! (F0, FNaN, rapids below the part) or exhaust memory (a tolerance below
//! what f64 resolves), naming the flag, and writes nothing.

use std::path::Path;
use std::process::Command;

/// A 20 × 20 mm plate 2 mm high, as an ASCII STL.
fn plate(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("plate.stl");
    let tri = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| {
        format!(
            "facet normal 0 0 1\nouter loop\nvertex {} {} {}\nvertex {} {} {}\nvertex {} {} {}\nendloop\nendfacet\n",
            a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]
        )
    };
    let mut s = String::from("solid plate\n");
    s += &tri([0.0, 0.0, 2.0], [20.0, 0.0, 2.0], [20.0, 20.0, 2.0]);
    s += &tri([0.0, 0.0, 2.0], [20.0, 20.0, 2.0], [0.0, 20.0, 2.0]);
    s += "endsolid plate\n";
    std::fs::write(&p, s).unwrap();
    p
}

#[test]
fn plan_raster_refuses_bad_feeds_clearances_and_tolerances_naming_the_flag() {
    let dir = std::env::temp_dir().join(format!("interpd-plan-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let stl = plate(&dir);
    let out = dir.join("out.ngc");
    let run = |extra: &[&str]| {
        let _ = std::fs::remove_file(&out);
        let o = Command::new(env!("CARGO_BIN_EXE_interpd"))
            .args([
                "plan",
                "raster",
                "--quiet",
                "--tool",
                "ball:4",
                "--stepover",
                "2",
            ])
            .arg("--stl")
            .arg(&stl)
            .arg("--out")
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    for (flags, says) in [
        (&["--feed", "0"][..], "--feed must be a positive"),
        (&["--feed=-5"][..], "--feed must be a positive"),
        (&["--feed", "nan"][..], "--feed must be a positive"),
        (
            &["--plunge-feed", "inf"][..],
            "--plunge-feed must be a positive",
        ),
        (
            &["--clearance=-100"][..],
            "--clearance must be a finite number >= 0",
        ),
        (
            &["--blend-tolerance=-0.001"][..],
            "--blend-tolerance must be a finite number of mm >= 0",
        ),
        (
            &["--blend-tolerance", "nan"][..],
            "--blend-tolerance must be a finite number of mm >= 0",
        ),
        (
            &["--chord-tolerance", "1e-15"][..],
            "--chord-tolerance 0.000000000000001 mm is below what f64 resolves",
        ),
    ] {
        let (ok, err) = run(flags);
        assert!(!ok, "{flags:?} accepted");
        assert!(err.contains(says), "{flags:?}: {err}");
        assert!(!out.exists(), "{flags:?} wrote {}", out.display());
    }
    // The same run with sane flags writes a program above the part.
    let (ok, err) = run(&["--feed", "1200", "--clearance", "3"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("F1200"), "{text}");
    // Dense moves run at speed: G64 P (1 µm by default) before any move;
    // `--blend-tolerance 0` leaves the controller's exact path.
    assert!(text.contains("G64 P0.001"), "{text}");
    let (ok, err) = run(&["--blend-tolerance", "0"]);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(!text.contains("G64"), "{text}");
    std::fs::remove_dir_all(&dir).ok();
}

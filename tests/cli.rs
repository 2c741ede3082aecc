//! The `gloam` binary as a user meets it: exit codes, one-line errors, no panics.

mod common;

use std::process::{Command, Output};

fn gloam(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gloam"))
        .args(args)
        .current_dir(common::repo())
        .output()
        .expect("run gloam")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn check_accepts_the_shipped_levels() {
    for level in ["levels/cornell.ron", "levels/first-light.ron"] {
        let output = gloam(&["check", level]);
        assert!(
            output.status.success(),
            "{level}: {}{}",
            text(&output.stdout),
            text(&output.stderr)
        );
        assert!(
            text(&output.stdout).contains(": ok:"),
            "{}",
            text(&output.stdout)
        );
    }
}

#[test]
fn check_lists_problems_and_exits_1() {
    let dir = common::scratch_dir("cli-check");
    let level = common::write(
        &dir,
        "broken.ron",
        "(\n    version: 1,\n    entities: [\n        (name: \"a\", transform: (scale: (1.0, -1.0, 1.0))),\n    ],\n)\n",
    );
    let output = gloam(&["check", level.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1));
    let stdout = text(&output.stdout);
    assert!(stdout.contains("broken.ron:4:"), "{stdout}");
    assert!(stdout.contains("scale must be positive"), "{stdout}");
    assert!(stdout.contains("no player spawn"), "{stdout}");
    assert!(!text(&output.stderr).contains("panicked"));
}

#[test]
fn bad_flags_are_one_line_and_exit_1() {
    for args in [
        &["check"][..],
        &["--frobnicate"],
        &["check", "a", "b"],
        &[
            "generate",
            "stress",
            "--triangles",
            "many",
            "--out",
            "x.glb",
        ],
    ] {
        let output = gloam(args);
        assert_eq!(output.status.code(), Some(1), "{args:?}");
        let stderr = text(&output.stderr);
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("gloam: "), "{stderr}");
    }
    assert!(gloam(&["--help"]).status.success());
}

#[test]
fn stress_mesh_generates_and_checks() {
    let dir = common::scratch_dir("cli-stress");
    let out = dir.join("stress.glb");
    let output = gloam(&[
        "generate",
        "stress",
        "--triangles",
        "5000",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", text(&output.stderr));
    let output = gloam(&["check", out.to_str().unwrap()]);
    assert!(output.status.success(), "{}", text(&output.stdout));
}

#[test]
fn unwritable_output_is_an_error_not_a_panic() {
    let output = gloam(&[
        "generate",
        "stress",
        "--triangles",
        "10",
        "--out",
        "/proc/gloam-cannot-write-here/x.glb",
    ]);
    assert_eq!(output.status.code(), Some(1));
    let stderr = text(&output.stderr);
    assert!(
        stderr.contains("x.glb") && !stderr.contains("panicked"),
        "{stderr}"
    );
}

#[test]
fn check_accepts_the_shared_samples() {
    let Some(samples) = common::shared("gltf-samples") else {
        return;
    };
    let Some(scenes) = common::shared("scenes") else {
        return;
    };
    let mut files = vec![scenes.join("dream-apartment.glb")];
    for model in std::fs::read_dir(samples)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_dir())
    {
        for variant in std::fs::read_dir(&model)
            .unwrap()
            .map(|e| e.unwrap().path())
        {
            files.extend(
                std::fs::read_dir(&variant)
                    .unwrap()
                    .map(|e| e.unwrap().path())
                    .filter(|p| p.extension().is_some_and(|e| e == "gltf" || e == "glb")),
            );
        }
    }
    assert!(files.len() >= 10);
    for file in files {
        let output = gloam(&["check", file.to_str().unwrap()]);
        assert!(
            output.status.success(),
            "{}: {}",
            file.display(),
            text(&output.stdout)
        );
    }
}

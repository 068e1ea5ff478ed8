//! The trainer's command line refuses sizes and numbers outside their limits before any work, with
//! a message that names the flag and what is allowed, and leaves an existing output untouched.

use std::process::Command;

/// One malformed invocation: its arguments and what the message must name.
struct Case {
    args: &'static [&'static str],
    names: &'static [&'static str],
}

const CASES: &[Case] = &[
    Case { args: &["fit", "--toy", "100000000000", "--model", "single-mlp"], names: &["--toy", "10000000"] },
    Case { args: &["fit", "--toy", "0", "--model", "single-mlp"], names: &["--toy", "allowed"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--lr", "nan"], names: &["--lr", "finite"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--lr=-1"], names: &["--lr", "positive"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--lr-final", "inf"], names: &["--lr-final"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--batch", "0"], names: &["--batch", "allowed"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--angle-frequencies", "17"], names: &["--angle-frequencies", "0..=16"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--position", "intrinsic:100000"], names: &["--position", "intrinsic:100000", "1..=4096"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--position", "extrinsic:40"], names: &["--position", "extrinsic:40", "frequencies"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--steps", "0"], names: &["--steps", "allowed"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--steps", "100000000000000"], names: &["--steps", "10000000"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--angle-frequencies", "200"], names: &["--angle-frequencies 200", "0..=16"] },
    Case { args: &["bench-step", "--batch", "100000000000", "--steps", "1"], names: &["--batch", "1048576"] },
    Case { args: &["bench-step", "--batch", "64", "--rounds", "0"], names: &["--rounds", "allowed"] },
    Case { args: &["synth", "--size", "100000"], names: &["--size 100000", "16384"] },
    Case { args: &["synth", "--sigma", "nan"], names: &["--sigma NaN", "finite"] },
    Case { args: &["synth", "--target-median", "nan"], names: &["--target-median NaN", "(0, 100]"] },
    Case { args: &["synth", "--target-median", "0"], names: &["--target-median 0", "(0, 100]"] },
    Case { args: &["synth", "--views", "100000000"], names: &["--views", "10000"] },
    Case { args: &["synth", "--train-lights", "100000000"], names: &["--train-lights", "10000"] },
    Case { args: &["synth", "--views", "5000", "--train-views", "5000", "--train-lights", "5000"], names: &["images", "200000"] },
    Case { args: &["synth", "--views", "2000", "--train-views", "2000", "--train-lights", "90", "--size", "2048"], names: &["bytes on disk"] },
    // Values that used to run as something else: a stride of 0 as 1, a layer count out of range
    // clamped while the variant kept the name, a data set without training images.
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--pixel-stride", "0"], names: &["--pixel-stride 0", "at least 1"] },
    Case { args: &["fit", "--toy", "100", "--model", "single-mlp", "--direction-layers", "255"], names: &["--direction-layers 255", "1..=6", "single-mlp"] },
    Case { args: &["fit", "--toy", "100", "--model", "additive-shared", "--direction-layers", "0"], names: &["--direction-layers 0", "1..=16"] },
    Case { args: &["fit", "--toy", "100", "--model", "rp", "--direction-layers", "2"], names: &["--direction-layers", "purely neural", "rp"] },
    Case { args: &["synth", "--views", "4", "--train-views", "0"], names: &["--train-views 0", "1..=4"] },
    Case { args: &["synth", "--train-lights", "0"], names: &["--train-lights 0", "training view"] },
    Case { args: &["synth", "--views", "4", "--train-views", "2", "--test-lights", "0"], names: &["--test-lights 0", "2 test views"] },
    Case { args: &["bench-step", "--batch", "64", "--only", "nonesuch"], names: &["--only \"nonesuch\"", "known", "single-mlp", "additive-shared"] },
];

#[test]
fn out_of_range_sizes_and_numbers_fail_fast_naming_the_flag() {
    let dir = std::env::temp_dir().join(format!("nbrdf-cli-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // An existing output that no refused run may touch.
    let keep = dir.join("keep.txt");
    std::fs::write(&keep, "previous output").unwrap();
    for case in CASES {
        let started = std::time::Instant::now();
        let mut command = Command::new(env!("CARGO_BIN_EXE_trainer"));
        command.args(case.args);
        if case.args[0] != "bench-step" {
            command.arg("--out").arg(&dir);
        }
        let out = command.output().unwrap();
        let message = String::from_utf8_lossy(&out.stderr);
        // 2: a value the command line parses into its typed request, refused by clap as a usage
        // error (the position encoding); 1: a value checked when the request runs.
        assert!(matches!(out.status.code(), Some(1 | 2)), "{:?}: exit status; {message}", case.args);
        for name in case.names {
            assert!(message.contains(name), "{:?}: the message names {name:?}: {message}", case.args);
        }
        assert!(!message.contains("cannot parse"), "{:?}: a range error is not a parse error: {message}", case.args);
        // Refused before any work: no training, no rendering.
        assert!(started.elapsed().as_secs() < 30, "{:?} took {:?}", case.args, started.elapsed());
    }
    assert_eq!(std::fs::read_to_string(&keep).unwrap(), "previous output");
    let entries: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(entries, vec![std::ffi::OsString::from("keep.txt")], "refused runs write nothing");
    std::fs::remove_dir_all(&dir).unwrap();
}

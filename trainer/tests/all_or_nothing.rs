//! Outputs are all or nothing: `synth` and `fit` killed mid-run (SIGKILL, SIGINT, SIGTERM) leave the
//! previous output byte for byte as it was and loadable; an interrupted run removes its staging folder
//! as it exits, and the next run removes what a killed one left.

use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::snapshot;

fn trainer() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_trainer"));
    c.stdout(Stdio::null()).stderr(Stdio::piped());
    // A shell that starts the tests in the background (`cargo test &`) leaves SIGINT ignored, and exec
    // keeps it ignored: the run must see the default disposition a terminal's Ctrl-C meets.
    // SAFETY: `signal` is async-signal-safe, as code between fork and exec must be.
    unsafe {
        c.pre_exec(|| {
            libc::signal(libc::SIGINT, libc::SIG_DFL);
            Ok(())
        });
    }
    c
}

fn run_ok(args: &[&str]) {
    let out = trainer().args(args).output().unwrap();
    assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
}


fn temps_in(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".nbrdf-tmp-"))
        .collect()
}

/// Waits until `ready` holds (the run is under way), then sends `signal`, reaps the child and returns
/// how it ended.
fn kill_when(mut child: Child, signal: i32, ready: impl Fn() -> bool) -> std::process::ExitStatus {
    let start = Instant::now();
    while !ready() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before it could be interrupted");
        }
        assert!(start.elapsed() < Duration::from_secs(120), "the run never got under way");
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: a plain signal to the child this test spawned and has not reaped yet.
    assert_eq!(unsafe { libc::kill(child.id() as i32, signal) }, 0);
    let status = child.wait().unwrap();
    assert!(!status.success(), "the run was interrupted");
    status
}

#[test]
fn synth_killed_mid_run_leaves_the_previous_data_set_intact() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("ds");
    let out_s = out.to_str().unwrap();
    let tiny = ["synth", "--quiet", "--size", "16", "--views", "2", "--train-views", "1", "--train-lights", "2", "--test-lights", "1"];
    run_ok(&[&tiny[..], &["--out", out_s]].concat());
    let before = snapshot(&out);
    trainer::dataset::Dataset::open(&out).unwrap();

    // A longer run of other arguments into the same folder, interrupted once its images are being
    // written: an interrupt (Ctrl-C, a scheduler's SIGTERM) removes the staging folder on the way out,
    // SIGKILL cannot.
    let long = ["synth", "--quiet", "--size", "128", "--views", "20", "--train-lights", "30", "--seed", "7", "--out", out_s];
    for signal in [libc::SIGINT, libc::SIGTERM, libc::SIGKILL] {
        let child = trainer().args(long).spawn().unwrap();
        let pid = child.id();
        let staging = root.path().join(format!(".nbrdf-tmp-{pid}-ds"));
        let status = kill_when(child, signal, || staging.join("views").join("00").join("001.exr").exists());
        assert_eq!(status.signal(), Some(signal), "the run ends by the signal it got");
        assert_eq!(snapshot(&out), before, "signal {signal}: the previous data set is unchanged");
        trainer::dataset::Dataset::open(&out).unwrap();
        let left = temps_in(root.path());
        if signal == libc::SIGKILL {
            assert!(!left.is_empty(), "the killed run left its staging folder");
        } else {
            assert_eq!(left, Vec::<String>::new(), "signal {signal}: the interrupted run removed its staging folder");
        }
    }

    // The next run removes the dead runs' staging folders and replaces the data set whole.
    let other = [&tiny[..], &["--seed", "3", "--out", out_s]].concat();
    run_ok(&other);
    assert_eq!(temps_in(root.path()), Vec::<String>::new());
    let after = snapshot(&out);
    assert_ne!(after, before, "another seed, other images");
    assert_eq!(after.keys().collect::<Vec<_>>(), before.keys().collect::<Vec<_>>(), "no file of the old set is left over");
}

#[test]
fn fit_killed_mid_run_leaves_the_previous_fit_intact() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("fit");
    let out_s = out.to_str().unwrap();
    let base = ["fit", "--toy", "2000", "--model", "single-mlp", "--position", "uniform", "--batch", "256", "--out", out_s];
    run_ok(&[&base[..], &["--steps", "4"]].concat());
    let before = snapshot(&out);
    let model = before.keys().find(|p| p.extension().is_some_and(|e| e == "nbrdf")).unwrap().clone();
    let partial = out.join(model.with_extension("partial.ckpt.json"));

    for signal in [libc::SIGKILL, libc::SIGINT] {
        let child = trainer().args(base).args(["--steps", "1000000", "--checkpoint-every", "2", "--seed", "9"]).spawn().unwrap();
        kill_when(child, signal, || partial.exists());
        let now = snapshot(&out);
        for (path, bytes) in &before {
            assert_eq!(now.get(path), Some(bytes), "signal {signal}: {} is unchanged", path.display());
        }
        nbrdf::ModelBuf::load(out.join(&model)).unwrap();
        std::fs::remove_file(&partial).unwrap();
    }

    // A finished run replaces the three files together and leaves no temporary file.
    run_ok(&[&base[..], &["--steps", "6", "--seed", "5"]].concat());
    assert_eq!(temps_in(&out), Vec::<String>::new());
    assert!(!partial.exists(), "the run's checkpoint became the finished one");
    let after = snapshot(&out);
    assert_eq!(after.keys().collect::<Vec<_>>(), before.keys().collect::<Vec<_>>());
    assert_ne!(after[&model], before[&model]);
    nbrdf::ModelBuf::load(out.join(&model)).unwrap();
}

/// `--resume` continues an interrupted run from its partial checkpoint; a checkpoint past `--steps`
/// is an error, not a silent exit 0.
#[test]
fn resume_continues_an_interrupted_run_and_refuses_a_checkpoint_past_the_steps() {
    let root = tempfile::tempdir().unwrap();
    let out = root.path().join("fit");
    let out_s = out.to_str().unwrap();
    let base = ["fit", "--toy", "2000", "--model", "lambert", "--position", "uniform", "--batch", "256", "--out", out_s];
    let child = trainer().args(base).args(["--steps", "1000000", "--checkpoint-every", "3"]).spawn().unwrap();
    let partial = out.join("lambert.partial.ckpt.json");
    kill_when(child, libc::SIGKILL, || partial.exists());
    let ckpt: serde_json::Value = serde_json::from_slice(&std::fs::read(&partial).unwrap()).unwrap();
    let step = ckpt["step"].as_u64().unwrap();
    assert!(step >= 3 && step.is_multiple_of(3), "{step}");

    let more = (step + 2).to_string();
    run_ok(&[&base[..], &["--steps", &more, "--resume"]].concat());
    let log: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("lambert.log.json")).unwrap()).unwrap();
    assert_eq!(log["steps_done"].as_u64(), Some(step + 2));
    assert!(!partial.exists());

    let before = snapshot(&out);
    let fewer = (step + 1).to_string();
    let r = trainer().args(base).args(["--steps", &fewer, "--resume"]).output().unwrap();
    let message = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{message}");
    assert!(message.contains("lambert.ckpt.json") && message.contains("--steps") && message.contains(&more), "{message}");
    assert_eq!(snapshot(&out), before);
}

/// The pid of a process that has ended.
fn dead_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    child.wait().unwrap();
    child.id()
}

/// Leftovers of dead writers go, those of live ones stay; a previous data set that a crash left under
/// its swapped-out name (the two-rename swap of platforms without an atomic exchange) is put back.
#[test]
fn stale_temporaries_are_removed_and_a_swapped_out_data_set_restored() {
    let root = tempfile::tempdir().unwrap();
    let dead = dead_pid();
    let mine = std::process::id();
    std::fs::write(root.path().join(format!(".nbrdf-tmp-{dead}-a.nbrdf")), b"").unwrap();
    std::fs::create_dir_all(root.path().join(format!(".nbrdf-tmp-{dead}-ds/views"))).unwrap();
    std::fs::write(root.path().join(format!(".nbrdf-tmp-{mine}-b.nbrdf")), b"").unwrap();
    std::fs::write(root.path().join(".nbrdf-tmp-x-c"), b"").unwrap();
    assert_eq!(nbrdf::io::remove_stale_temps(root.path()), 2);
    let mut left = temps_in(root.path());
    left.sort();
    assert_eq!(left, vec![format!(".nbrdf-tmp-{mine}-b.nbrdf"), ".nbrdf-tmp-x-c".to_string()]);

    // A data set swapped out by a writer that died before putting the new one in place.
    let out = root.path().join("ds");
    let tiny = ["synth", "--quiet", "--size", "16", "--views", "2", "--train-views", "1", "--train-lights", "1", "--test-lights", "1"];
    run_ok(&[&tiny[..], &["--out", out.to_str().unwrap()]].concat());
    let before = snapshot(&out);
    let swapped = root.path().join(format!(".nbrdf-tmp-{}-previous-ds", dead_pid()));
    std::fs::rename(&out, &swapped).unwrap();
    let staging = trainer::staging::StagedDir::new(&out, "data set", |_| true).unwrap();
    drop(staging);
    assert!(!swapped.exists());
    assert_eq!(snapshot(&out), before);
}

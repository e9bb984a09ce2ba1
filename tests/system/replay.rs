//! `launch --record` and `orchestrator replay` with real processes, on seed 000's fixed-offset
//! scenario (short): recording changes no telemetry (multi-process and reference), replaying agent
//! 3 gives every share bit for bit, a share tampered in the file is named (step, field) with exit
//! 1, and bad input (an agent out of range, no recording, a damaged file, no run directory) is
//! exit 2 naming what is wrong. Heavy tests are serialised by [`cohort::heavy`].

use std::path::{Path, PathBuf};
use std::process::Output;

use cohort::OutputWithin;
use cohort::{describe_output, heavy_scratch, launch_scenario, orchestrator_command, repo_root, telemetry_bits};
use cohort_wire::layout;
use cohort_wire::msg::Share;

/// 2 s of sim time: 200 steps.
const STEPS: u64 = 200;

fn launch(out: &Path, extra: &[&str]) {
    let file = repo_root().join("topologies/fig1-fixed.toml");
    let mut args = vec!["--duration", "2"];
    args.extend_from_slice(extra);
    let o = launch_scenario(&file, out, &args);
    assert!(o.status.success(), "{}", describe_output(&o));
}

fn replay(run_dir: &Path, agent: &str) -> Output {
    orchestrator_command()
        .arg("replay")
        .arg(run_dir)
        .args(["--agent", agent])
        .output_within(cohort::RUN_LIMIT, "replay of an agent")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

/// Rewrite an MCAP file with one byte of one message changed: byte `offset` of the share on
/// `topic` whose header names `step` (the file stays a valid MCAP, so only the content differs).
fn tamper(path: &Path, topic: &str, step: u64, offset: usize) {
    rewrite(path, topic, step, offset, true);
}

/// [`tamper`], keeping the file's attachments or not.
fn rewrite(path: &Path, topic: &str, step: u64, offset: usize, attachments: bool) {
    let buf = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().expect("a summary");
    let tmp = path.with_extension("tampered");
    {
        let file = std::io::BufWriter::new(std::fs::File::create(&tmp).unwrap());
        let mut w = mcap::WriteOptions::new().compression(Some(mcap::Compression::Zstd)).create(file).unwrap();
        for i in &summary.metadata_indexes {
            w.write_metadata(&mcap::read::metadata(&buf, i).unwrap()).unwrap();
        }
        for i in summary.attachment_indexes.iter().filter(|_| attachments) {
            w.attach(&mcap::read::attachment(&buf, i).unwrap()).unwrap();
        }
        let mut flipped = 0;
        for m in mcap::MessageStream::new(&buf).unwrap() {
            let mut m = m.unwrap();
            if m.channel.topic == topic && layout::share_from_bytes(&m.data).unwrap().header.step == step {
                m.data.to_mut()[offset] ^= 0x01;
                flipped += 1;
            }
            w.write(&m).unwrap();
        }
        assert_eq!(flipped, 1, "one share of step {step} on {topic}");
        w.finish().unwrap();
    }
    std::fs::rename(&tmp, path).unwrap();
}

/// The run of [`a_restarted_agent_replays_each_incarnation_from_its_own_recording`]: 8 s (800
/// steps), agent 3 killed at 6 s and relaunched at 6.5 s from its latest checkpoint (step 500).
fn launch_with_restart(run: &Path) {
    let file = repo_root().join("topologies/fig1-fixed.toml");
    let args = ["--duration", "8", "--record", "--fault", "restart:agent=3@t=6,for=0.5"];
    let o = launch_scenario(&file, run, &args);
    assert!(o.status.success(), "{}", describe_output(&o));
}

#[test]
fn fig1_fixed_recorded_agent_3_replays_bit_for_bit_and_a_tampered_share_is_named() {
    let (_g, dir) = heavy_scratch("replay");
    let (rec, plain) = (dir.join("rec"), dir.join("plain"));
    launch(&rec, &["--record"]);
    launch(&plain, &[]);
    assert_eq!(telemetry_bits(&rec), telemetry_bits(&plain), "--record changed the telemetry");
    for i in 1..=6 {
        assert!(rec.join(format!("record/agent-{i}.mcap")).is_file(), "no recording of agent {i}");
    }

    let o = replay(&rec, "3");
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    assert!(
        stdout(&o).contains(&format!("replayed {STEPS} steps of agent 3: all {STEPS} shares identical")),
        "{}",
        describe_output(&o)
    );

    // One bit of values[4] of agent 3's share of step 100, as the file holds it.
    let mcap3 = rec.join("record/agent-3.mcap");
    let pristine = std::fs::read(&mcap3).unwrap();
    tamper(&mcap3, "/share/agent-3", 100, std::mem::offset_of!(Share, values) + 4 * 8);
    let o = replay(&rec, "3");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    let out = stdout(&o);
    assert!(out.contains("first mismatch: agent 3's share of step 100") && out.contains("(values[4])"), "{out}");
    assert!(out.contains(&format!("1 of {STEPS} shares differ")), "{out}");

    // A damaged file (a byte flipped in its compressed data) is bad input, named.
    let mut damaged = pristine.clone();
    damaged[pristine.len() / 2] ^= 0x20;
    std::fs::write(&mcap3, &damaged).unwrap();
    let o = replay(&rec, "3");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(stderr(&o).contains("agent-3.mcap"), "{}", describe_output(&o));
    std::fs::write(&mcap3, &pristine).unwrap();

    for (run, agent, says) in [
        (&rec, "7", "--agent 7: out of range"),
        (&rec, "0", "--agent 0: out of range"),
        (&plain, "3", "no recording here"),
        (&dir.join("nowhere"), "3", "no such run directory"),
    ] {
        let o = replay(run, agent);
        assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
        assert!(stderr(&o).contains(says), "expected {says:?}\n{}", describe_output(&o));
    }
}

#[test]
fn a_reference_run_records_too_and_its_agent_replays_bit_for_bit() {
    let (_g, dir) = heavy_scratch("replayref");
    let (rec, plain): (PathBuf, PathBuf) = (dir.join("rec"), dir.join("plain"));
    launch(&rec, &["--record", "--reference"]);
    launch(&plain, &[]);
    assert_eq!(telemetry_bits(&rec), telemetry_bits(&plain), "--record --reference changed the telemetry");
    let o = replay(&rec, "3");
    assert!(stdout(&o).contains(&format!("all {STEPS} shares identical")), "{}", describe_output(&o));
}

#[test]
fn a_restarted_agent_replays_each_incarnation_from_its_own_recording() {
    let (_g, dir) = heavy_scratch("replay-restart");
    let run = dir.join("run");
    launch_with_restart(&run);
    let (first, relaunch) = (run.join("record/agent-3.mcap"), run.join("record/agent-3.1.mcap"));
    assert!(first.is_file() && relaunch.is_file(), "one recording per incarnation");
    // The relaunch's recording carries the checkpoint it resumed from, byte for byte.
    let rec = cohort_runtime::recording::reader::read(&relaunch).unwrap();
    let carried = &rec.attachment(cohort_runtime::recording::RESTORED_FROM).expect("the checkpoint").data;
    assert_eq!(carried, &std::fs::read(run.join("checkpoints/agent-3.loaded.ckpt")).unwrap());
    // Every incarnation by default: the first up to where its file stops (SIGKILLed), the
    // relaunch from its checkpoint of step 500 over its 150 shares (steps 650..=799).
    let o = replay(&run, "3");
    let out = stdout(&o);
    assert_eq!(o.status.code(), Some(0), "{}", describe_output(&o));
    assert!(out.contains("steps of agent 3: all "), "{}", describe_output(&o));
    assert!(
        out.contains("agent 3 (relaunch 1, resumed from its checkpoint of step 500): all 150 shares identical"),
        "{}",
        describe_output(&o)
    );
    assert!(run.join("replay/agent-3.1/telemetry").is_dir(), "the relaunch's replay beside the first's");
    // A share of the relaunch tampered: exit 1 naming the relaunch and the step.
    rewrite(&relaunch, "/share/agent-3", 700, std::mem::offset_of!(Share, values) + 4 * 8, true);
    let o = orchestrator_command()
        .arg("replay")
        .arg(&run)
        .args(["--agent", "3", "--incarnation", "1"])
        .output_within(cohort::RUN_LIMIT, "replay of agent 3's relaunch");
    assert_eq!(o.status.code(), Some(1), "{}", describe_output(&o));
    assert!(stdout(&o).contains("first mismatch: agent 3 (relaunch 1"), "{}", describe_output(&o));
    assert!(stdout(&o).contains("share of step 700"), "{}", describe_output(&o));
    // Without the checkpoint a relaunch cannot be replayed: exit 2 saying so.
    rewrite(&relaunch, "/share/agent-3", 700, std::mem::offset_of!(Share, values) + 4 * 8, false);
    let o = replay(&run, "3");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(stderr(&o).contains("without the checkpoint it resumed from"), "{}", describe_output(&o));
}

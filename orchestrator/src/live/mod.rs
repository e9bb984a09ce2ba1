//! `--live [ADDR]`: a live Foxglove view of a running launch (or of each run of a soak), served
//! over the Foxglove WebSocket protocol by the `foxglove` crate from the orchestrator alone.
//!
//! **Where the data come from.** Nothing is added to the lockstep processes: the plant and every
//! agent already append their telemetry rows to a journal (`telemetry/<proc>.rows`, raw f64s, a
//! `write` every few rows; see `cohort_runtime::parquet_out`), and the orchestrator already sees
//! the progress (its progress hook) and the timeline (faults carried out, roster changes; through
//! `cohort_supervisor::observe`). A thread of the orchestrator ([`run`]) reads them every 50 ms
//! of wall time, keeps the rows of every `1 / (rate · dt)`-th step (`--live-rate HZ`, default 20
//! messages per sim second) and publishes them as they come, at most `rate` per process per
//! second of wall time (the newest first: a run faster than real time is shown at wall speed; a
//! real-time run keeps every kept row). The telemetry is the same with or without `--live`
//! (tested bit for bit); the cost is the orchestrator's thread reading files on cores the lockstep
//! shares — without the wall-time cap a fig1 run at 21 000 steps/s lost 20–27 % of its speed,
//! with it none measurable (`orchestrator bench --only live/`).
//!
//! **Channels.** `/scene` (`foxglove.SceneUpdate`, [`scene`]): each body the paper declares
//! (`RunHooks::scene`: which telemetry columns are its position, and which make its
//! algorithm's estimate) as a sphere at its truth and a ghost at the estimate, and the
//! communication graph as lines coloured by link state (green alive, orange delayed, red
//! dropped or corrupted, grey a dead end). `/telemetry/<proc>` (JSON, a JSON schema with every
//! Parquet column's name and unit): the process's row, values bit for bit as in its file (JSON
//! numbers in shortest round-trip form; a non-finite value is null). `/roster`
//! (`foxglove.Log`): the roster at the start and every timeline event. `/progress` (JSON): step,
//! steps, sim time, steps/s, clients. Log times are sim time (step × `dt_s`, ns), as in the MCAP
//! recording; the recording's channels (`/measurement/plant`, `/share/agent-<j>`) are the
//! agents' messages, which the orchestrator does not see, so the two share no channel.
//!
//! **Clients.** Any number; each has a bounded queue ([`server`]) whose oldest messages go when
//! it stalls, so a slow or stalled client costs the run nothing. A client that subscribes late
//! gets the latest scene, rows and progress and the whole roster log at once.
//!
//! **Limits.** CSV telemetry (`run.telemetry = "csv"`) is followed as its writers' 64 KiB buffers
//! reach the file, so its rows come in bursts. In a multi-host run the journals of processes on
//! other machines are on those machines: every 200 ms the thread asks each host's daemon for its
//! processes' new rows (`rows`, decimated there, the newest `rate` per process, one small reply a
//! process; `cohort_supervisor::observe::remote_rows`), so they show a fraction of a second
//! later than local ones; a host that does not answer within 1 s shows nothing new until it does.
//! A remote process's last rows after the final poll are in its Parquet file, not live.

pub mod client;
mod run;
mod scene;
mod server;

pub use run::LiveRun;
pub use server::{Options, STEP, start, started};

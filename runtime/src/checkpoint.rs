//! Agent checkpoints: an agent's full state every `run.checkpoint_every_steps` steps, so a
//! restarted process resumes where its predecessor was. A file is checked end to end before a
//! single byte of it is used — magic, schema version, run, agent, algorithm, length, CRC-32 — and
//! a refused file is an error naming the file and the reason, never a half-loaded state. The run
//! id ties a checkpoint to the run that wrote it: one copied in from another run (another seed,
//! another scenario, the same scenario run before) is refused, however valid.
//!
//! Layout (little-endian): `COHORTCK` · u32 version · u64 run id · u32 agent id · u64 step · u32 kind length ·
//! kind (UTF-8) · u64 payload length · payload (bincode: algorithm state and the driver's held
//! neighbour values) · u32 CRC-32 of everything before it.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

const MAGIC: &[u8; 8] = b"COHORTCK";
/// Bumped whenever the layout or the meaning of the payload changes.
pub const CHECKPOINT_VERSION: u32 = 2;

/// What a checkpoint restores: the algorithm's own bytes and the driver's last valid share of
/// each neighbour (id, step, values).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentState {
    pub algorithm: Vec<u8>,
    pub held: Vec<(u32, u64, Vec<f64>)>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    /// The run that wrote it (`DriveParams::run_id`, the orchestrator's random id of the run).
    pub run_id: u64,
    pub agent: u32,
    /// The step the agent is about to start (its state is at t = step·dt).
    pub step: u64,
    pub kind: String,
    pub state: AgentState,
}

/// A checkpoint file refused: which file, and why.
#[derive(Debug, thiserror::Error)]
#[error("checkpoint {}: {problem}", path.display())]
pub struct CheckpointError {
    pub path: PathBuf,
    pub problem: CheckpointProblem,
}

/// Why a checkpoint file was refused.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointProblem {
    #[error("cannot read: {0}")]
    Read(#[from] std::io::Error),
    #[error(transparent)]
    Decode(#[from] DecodeCheckpointError),
    #[error(transparent)]
    Resume(#[from] ResumeError),
}

/// Why bytes are not this agent's checkpoint of this run ([`Checkpoint::decode`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeCheckpointError {
    #[error("not a Cohort checkpoint (bad magic)")]
    BadMagic,
    #[error("schema version {found}, this build reads version {CHECKPOINT_VERSION}")]
    Version { found: u32 },
    #[error("truncated")]
    Truncated,
    #[error("checksum mismatch (stored {stored:08x}, computed {computed:08x}): the file is corrupted")]
    Checksum { stored: u32, computed: u32 },
    #[error(
        "written by run {found:016x}, not this run ({expected:016x}): a checkpoint of another run \
         (another seed or scenario, or an earlier run) is never restored"
    )]
    OtherRun { found: u64, expected: u64 },
    #[error("written by agent {found}, not agent {expected}")]
    OtherAgent { found: u32, expected: u32 },
    #[error("algorithm name is not UTF-8")]
    KindNotUtf8,
    #[error("holds the state of algorithm {found:?}, this agent runs {expected:?}")]
    OtherAlgorithm { found: String, expected: String },
    #[error("{0} trailing bytes after the payload")]
    Trailing(usize),
    #[error("payload: {0}")]
    Payload(String),
    #[error("payload longer than its state")]
    PayloadTooLong,
}

/// Why a valid checkpoint cannot resume an agent relaunched at a step ([`Checkpoint::check_resume`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ResumeError {
    #[error("relaunch step {relaunch_step} is past the run's last step {last_step}")]
    PastTheEnd { relaunch_step: u64, last_step: u64 },
    #[error(
        "holds the state at step {step}, after the relaunch step {relaunch_step}: it cannot be from this run's past"
    )]
    FromTheFuture { step: u64, relaunch_step: u64 },
}

/// Where agent `id`'s latest checkpoint lives in a run directory.
pub fn path_for(run_dir: &Path, id: u32) -> PathBuf {
    run_dir.join("checkpoints").join(format!("agent-{id}.ckpt"))
}

/// Write an encoded checkpoint (its folder made if missing) atomically, as [`Checkpoint::write`]
/// does; an error names the file.
pub fn write_encoded(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let written = match path.parent() {
        Some(dir) => std::fs::create_dir_all(dir).and_then(|_| crate::record::write_atomic(path, bytes)),
        None => crate::record::write_atomic(path, bytes),
    };
    written.map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", path.display())))
}

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_little_endian().with_fixed_int_encoding()
}

impl Checkpoint {
    pub fn encode(&self) -> Vec<u8> {
        let payload = bincode::serde::encode_to_vec(&self.state, config()).expect("plain data always encodes");
        let mut out = Vec::with_capacity(payload.len() + 64);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&CHECKPOINT_VERSION.to_le_bytes());
        out.extend_from_slice(&self.run_id.to_le_bytes());
        out.extend_from_slice(&self.agent.to_le_bytes());
        out.extend_from_slice(&self.step.to_le_bytes());
        out.extend_from_slice(&(self.kind.len() as u32).to_le_bytes());
        out.extend_from_slice(self.kind.as_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&payload);
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Decode and check `bytes` as run `run_id`'s checkpoint of agent `agent` for algorithm `kind`.
    pub fn decode(bytes: &[u8], run_id: u64, agent: u32, kind: &str) -> Result<Self, DecodeCheckpointError> {
        use DecodeCheckpointError as E;
        if bytes.len() < MAGIC.len() + 4 || &bytes[..8] != MAGIC {
            return Err(E::BadMagic);
        }
        let (body, crc) = bytes.split_at(bytes.len().saturating_sub(4));
        let version = u32::from_le_bytes(body[8..12].try_into().expect("4 bytes"));
        if version != CHECKPOINT_VERSION {
            return Err(E::Version { found: version });
        }
        let want = crc32fast::hash(body);
        let got = u32::from_le_bytes(crc.try_into().map_err(|_| E::Truncated)?);
        if want != got {
            return Err(E::Checksum { stored: got, computed: want });
        }
        let mut r = Reader { b: body, at: 12 };
        let run = r.u64()?;
        if run != run_id {
            return Err(E::OtherRun { found: run, expected: run_id });
        }
        let id = r.u32()?;
        if id != agent {
            return Err(E::OtherAgent { found: id, expected: agent });
        }
        let step = r.u64()?;
        let kind_len = r.u32()? as usize;
        let k = std::str::from_utf8(r.take(kind_len)?).map_err(|_| E::KindNotUtf8)?;
        if k != kind {
            return Err(E::OtherAlgorithm { found: k.to_string(), expected: kind.to_string() });
        }
        let len = r.u64()? as usize;
        let payload = r.take(len)?;
        if r.at != body.len() {
            return Err(E::Trailing(body.len() - r.at));
        }
        let (state, used): (AgentState, usize) =
            bincode::serde::decode_from_slice(payload, config()).map_err(|e| E::Payload(e.to_string()))?;
        if used != payload.len() {
            return Err(E::PayloadTooLong);
        }
        Ok(Self { run_id, agent, step, kind: k.to_string(), state })
    }

    /// Write atomically (a reader never sees half a file): to a temporary name, then rename.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        write_encoded(path, &self.encode())
    }

    /// Whether this checkpoint can resume an agent relaunched at step `relaunch_step` of a run of
    /// `n_steps`: it must hold a state from before the relaunch (a CRC-valid file can still name
    /// any step, and one from the future would leave the agent waiting for measurements the plant
    /// already sent), and the relaunch must be inside the run.
    pub fn check_resume(&self, relaunch_step: u64, n_steps: u64) -> Result<(), ResumeError> {
        if relaunch_step >= n_steps {
            return Err(ResumeError::PastTheEnd { relaunch_step, last_step: n_steps.saturating_sub(1) });
        }
        if self.step > relaunch_step {
            return Err(ResumeError::FromTheFuture { step: self.step, relaunch_step });
        }
        Ok(())
    }

    pub fn read(path: &Path, run_id: u64, agent: u32, kind: &str) -> Result<Self, CheckpointError> {
        let err = |problem: CheckpointProblem| CheckpointError { path: path.to_path_buf(), problem };
        let bytes = std::fs::read(path).map_err(|e| err(e.into()))?;
        Self::decode(&bytes, run_id, agent, kind).map_err(|e| err(e.into()))
    }
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeCheckpointError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len()).ok_or(DecodeCheckpointError::Truncated)?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, DecodeCheckpointError> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Result<u64, DecodeCheckpointError> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
}

/// Encode an algorithm's state (its serde form) as checkpoint bytes.
pub fn encode_state<T: Serialize>(state: &T) -> Vec<u8> {
    bincode::serde::encode_to_vec(state, config()).expect("algorithm state always encodes")
}

/// Decode an algorithm's state; the whole input must be used.
pub fn decode_state<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> Result<T, DecodeStateError> {
    let (v, used) =
        bincode::serde::decode_from_slice(bytes, config()).map_err(|e| DecodeStateError::Bincode(e.to_string()))?;
    if used != bytes.len() {
        return Err(DecodeStateError::Trailing(bytes.len() - used));
    }
    Ok(v)
}

/// Why bytes are not an algorithm's state ([`decode_state`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DecodeStateError {
    /// bincode's reason (a short or malformed input).
    #[error("{0}")]
    Bincode(String),
    #[error("{0} trailing bytes after the algorithm state")]
    Trailing(usize),
}

/// For a field holding scenario configuration inside an algorithm's state: bincode is not
/// self-describing, so a struct that skips absent optional keys (as the scenario's do, for TOML)
/// would not decode again. Such a field goes in as JSON text. Use with
/// `#[serde(with = "cohort_runtime::checkpoint::as_json")]`.
pub mod as_json {
    use serde::{Deserialize, Deserializer, Serialize, Serializer, de::DeserializeOwned};

    pub fn serialize<T: Serialize, S: Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
        serde_json::to_string(v).map_err(serde::ser::Error::custom)?.serialize(s)
    }

    pub fn deserialize<'de, T: DeserializeOwned, D: Deserializer<'de>>(d: D) -> Result<T, D::Error> {
        serde_json::from_str(&String::deserialize(d)?).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const RUN: u64 = 0x1234_5678_9abc_def0;

    fn sample() -> Checkpoint {
        Checkpoint {
            run_id: RUN,
            agent: 2,
            step: 1200,
            kind: "lb-dnn-servicing".into(),
            state: AgentState { algorithm: vec![1, 2, 3, 250], held: vec![(1, 1199, vec![0.5, -1.25])] },
        }
    }

    #[test]
    fn round_trips_exactly() {
        let c = sample();
        assert_eq!(Checkpoint::decode(&c.encode(), RUN, 2, "lb-dnn-servicing").unwrap(), c);
    }

    #[test]
    fn every_kind_of_damage_is_refused_with_its_reason() {
        let good = sample().encode();
        let mut flipped = good.clone();
        let mid = flipped.len() / 2;
        flipped[mid] ^= 0x40;
        let mut version = good.clone();
        version[8] = 9;
        let cases: Vec<(Vec<u8>, &str, u64, u32, &str)> = vec![
            (flipped, "checksum mismatch", RUN, 2, "lb-dnn-servicing"),
            (good[..good.len() - 7].to_vec(), "checksum", RUN, 2, "lb-dnn-servicing"),
            (version, "schema version 9", RUN, 2, "lb-dnn-servicing"),
            (b"hello world, not a checkpoint".to_vec(), "bad magic", RUN, 2, "lb-dnn-servicing"),
            (good.clone(), "not agent 3", RUN, 3, "lb-dnn-servicing"),
            (good.clone(), "this agent runs \"coast\"", RUN, 2, "coast"),
            (
                good.clone(),
                "written by run 123456789abcdef0, not this run (0000000000000001)",
                1,
                2,
                "lb-dnn-servicing",
            ),
            (Vec::new(), "bad magic", RUN, 2, "lb-dnn-servicing"),
        ];
        for (bytes, says, run, agent, kind) in cases {
            let e = Checkpoint::decode(&bytes, run, agent, kind).unwrap_err().to_string();
            assert!(e.contains(says), "expected {says:?}, got {e:?}");
        }
    }

    #[test]
    fn a_step_after_the_relaunch_or_past_the_run_is_refused() {
        // Issue 18, finding 6: a CRC-valid checkpoint of step 2^63, or ahead of the relaunch
        // step, was accepted and the agent then waited until it was declared dead.
        let mut c = sample(); // step 1200
        assert_eq!(c.check_resume(1200, 36_000), Ok(()));
        assert_eq!(c.check_resume(3000, 36_000), Ok(()));
        assert!(c.check_resume(1199, 36_000).unwrap_err().to_string().contains("after the relaunch step 1199"));
        assert!(c.check_resume(36_000, 36_000).unwrap_err().to_string().contains("past the run's last step"));
        c.step = 1 << 63;
        let bytes = c.encode();
        let decoded = Checkpoint::decode(&bytes, RUN, 2, "lb-dnn-servicing").unwrap();
        assert!(decoded.check_resume(3000, 36_000).is_err());
    }

    #[test]
    fn read_names_the_file() {
        let dir = std::env::temp_dir().join(format!("cohort-ckpt-{}", std::process::id()));
        let p = path_for(&dir, 2);
        sample().write(&p).unwrap();
        assert_eq!(Checkpoint::read(&p, RUN, 2, "lb-dnn-servicing").unwrap(), sample());
        let e = Checkpoint::read(&path_for(&dir, 5), RUN, 5, "x").unwrap_err().to_string();
        assert!(e.contains("agent-5.ckpt") && e.contains("cannot read"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

//! Checkpoints (`output.checkpoint_every`): the whole state of a run at a recorded step, so that
//! `rbsm run SCENE --resume DIR` goes on from there and ends with the outputs, byte for byte,
//! of a run that was never stopped. One file, `DIR/checkpoint.bin`, written atomically: the
//! state (postcard), then a 64-bit FNV-1a checksum of it, so that a file changed in any one
//! byte (or cut short) is refused, not resumed; what it restores is then checked against the
//! model (`CentralDifference::restore`).

use crate::analysis::setup::Overrides;
use crate::error::{Error, Result};
use crate::input::scene::Scene;
use crate::output;
use crate::step::integrator::{Energy, State};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The file's name in the output folder.
pub const FILE: &str = "checkpoint.bin";

/// Bumped when the layout changes: an older checkpoint is then refused, not misread (4: the
/// failing interfaces' points in the order of the sweep, `Model::failing_interfaces`).
const FORMAT: u32 = 4;

/// What a run needs to go on from a checkpoint.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Checkpoint {
    format: u32,
    /// [`fingerprint`] of the scene and options the run was started with.
    fingerprint: u64,
    /// The integrator's state, contact included.
    pub state: State,
    /// Bytes of `history.csv` up to the checkpoint's step.
    pub history_bytes: u64,
    /// The VTK frames written up to the checkpoint's step: time and name under the folder.
    pub frames: Vec<(f64, String)>,
    /// The energies at the first recorded step (for the summary).
    pub first: Option<Energy>,
    /// The largest rotation of a meshed body seen so far (rad).
    pub rotation: f64,
}

/// FNV-1a, 64 bits. Each step `h ← (h ⊕ b) · p` is a bijection of `h` for a given byte, so two
/// inputs of one length that differ in a single byte always hash differently.
fn fnv1a(bytes: impl IntoIterator<Item = u8>) -> u64 {
    bytes.into_iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// A hash (FNV-1a, 64 bits) of everything that decides a run: the scene as parsed (its `Debug`
/// form, which prints every number exactly) and the command-line overrides.
pub fn fingerprint(scene: &Scene, opts: &Overrides) -> u64 {
    // `--exact-dt-crit` changes the step of a `dt_factor` run (in its last digits); added
    // only when set, so that earlier checkpoints keep their fingerprint.
    let text = format!(
        "{scene:?}|{:?}|{:?}|{:?}|{:?}{}",
        opts.evaluator,
        opts.dt.map(f64::to_bits),
        opts.dt_factor.map(f64::to_bits),
        opts.steps,
        if opts.exact_dt_crit { "|exact" } else { "" }
    );
    fnv1a(text.bytes())
}

impl Checkpoint {
    /// A checkpoint of a run of `scene` with `opts`.
    pub fn new(
        scene: &Scene,
        opts: &Overrides,
        state: State,
        history_bytes: u64,
        frames: Vec<(f64, String)>,
        first: Option<Energy>,
        rotation: f64,
    ) -> Self {
        Checkpoint {
            format: FORMAT,
            fingerprint: fingerprint(scene, opts),
            state,
            history_bytes,
            frames,
            first,
            rotation,
        }
    }

    /// Writes `DIR/checkpoint.bin` atomically.
    ///
    /// # Errors
    /// `DIR/checkpoint.bin` cannot be written (no folder `DIR`, no permission, disk full), or the
    /// state cannot be encoded.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(FILE);
        let mut bytes = postcard::to_stdvec(self)
            .map_err(|e| Error::io(&path, std::io::Error::other(e.to_string())))?;
        let sum = fnv1a(bytes.iter().copied());
        bytes.extend_from_slice(&sum.to_le_bytes());
        output::write_atomic(&path, &bytes)
    }

    /// Reads `DIR/checkpoint.bin` and checks that it belongs to a run of `scene` with `opts`.
    ///
    /// # Errors
    /// `DIR/checkpoint.bin` is missing or cannot be read; it is damaged (its checksum does not
    /// match), of another format of rbsm, or written by a run of another scene or other overrides
    /// (another [`fingerprint`]).
    pub fn read(dir: &Path, scene: &Scene, opts: &Overrides) -> Result<Checkpoint> {
        let path: PathBuf = dir.join(FILE);
        let bytes = std::fs::read(&path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => Error::io(
                &path,
                std::io::Error::other(
                    "no checkpoint here: a run writes one only when its scene sets \
                    `output.checkpoint_every`, and removes it once it has finished",
                ),
            ),
            _ => Error::io(&path, e),
        })?;
        let bad = |why: String| Error::io(&path, std::io::Error::other(why));
        let damaged = || {
            bad(
                "damaged: its checksum does not match its contents (a changed or missing \
                byte); start the run again"
                    .into(),
            )
        };
        let (body, sum) = bytes
            .split_at_checked(bytes.len().wrapping_sub(8))
            .ok_or_else(damaged)?;
        if fnv1a(body.iter().copied()).to_le_bytes() != sum {
            return Err(damaged());
        }
        let checkpoint: Checkpoint = postcard::from_bytes(body)
            .map_err(|e| bad(format!("not a checkpoint of this version of rbsm ({e})")))?;
        if checkpoint.format != FORMAT {
            return Err(bad(format!(
                "checkpoint format {} (this rbsm reads {FORMAT})",
                checkpoint.format
            )));
        }
        if checkpoint.fingerprint != fingerprint(scene, opts) {
            return Err(bad(
                "written by a run of another scene or other options (--evaluator, \
                --dt, --dt-factor, --steps, --exact-dt-crit): resume with the scene and options the run was \
                started with"
                    .into(),
            ));
        }
        Ok(checkpoint)
    }
}

//! The seqlock behind [`Published`]: one buffer of 32-bit atomics and a sequence number.
//!
//! Writer ([`Published::publish_with`], the updater only): sequence to odd (Relaxed), a
//! Release fence, every value (Relaxed), sequence to even (Release). Reader
//! ([`Published::read_with`], the applier only): sequence (Acquire), and if it is even every
//! value (Relaxed), an Acquire fence, the sequence again (Relaxed); the copy is whole only
//! if the two sequences are equal. The fences pair up: a reader that saw any value of a
//! publication that had begun after its first load also sees that publication's odd
//! sequence at the re-check, so it drops the copy.
//!
//! Only loads and stores are used, no read-modify-write: every Cortex-M has them.
//!
//! # Checked by loom
//! With `--cfg loom` the atomics and the fence are loom's, and the `model` tests run one
//! writer thread and one reader thread through every execution loom finds: every
//! interleaving, and every store each load may read under loom's memory model (with one
//! publication against the reader: all of them, 231 252 executions; with two: those with at
//! most 3 preemptions, 165 088). `cargo xtask loom` runs them, then runs them again on each
//! mutant (`--cfg qfa_mutant="NAME"`, one ordering or step of this file weakened or removed)
//! and fails unless the model fails on every one; `cargo xtask test` runs the clean model.
//! Normal builds contain none of the mutants' code.
//!
//! What loom does not cover (its docs, "Limitations and Caveats"): it does not reorder a
//! thread's own operations, so a load reads only a store already made in the execution (no
//! load buffering), and each atomic keeps only its last 7 stores. This protocol's argument
//! (Boehm, "Can seqlocks get along with programming language memory models?", 2012, the
//! fence version) rests only on the Release/Acquire synchronisation of its fences and
//! stores with the loads that read them, which loom models; each mutant breaks one such
//! pairing, and each is caught. The sequence, the most-stored word, gets 7 stores in the
//! largest test, so no store a load could read is forgotten.

#[cfg(not(loom))]
use core::sync::atomic::{fence, AtomicU32, Ordering};
#[cfg(loom)]
use loom::sync::atomic::{fence, AtomicU32, Ordering};

use super::Status;

/// Flag in a published flags word: the set has a misalignment matrix.
pub(super) const HAS_MISALIGN: u32 = 1 << 17;
/// The slow path's status flags take bits 0–8 of the flags word (checked at compile time).
/// [`Status::DT_IMPLAUSIBLE`] is the fast path's own, judged per cycle, and never published.
const STATUS_BITS: u32 = 0x1FF;
const _: () = assert!(
    (Status::all().bits() & !Status::DT_IMPLAUSIBLE.bits()) as u32 & !STATUS_BITS == 0,
    "the published Status outgrew its 9 bits"
);
/// The epoch of good readings (a wrapping `u8`) sits in flags bits 9–16.
const EPOCH_SHIFT: u32 = 9;
/// The oldest stream's age, in [`AGE_STEPS`]ths of the stale threshold, sits in the flags
/// word's top 14 bits, so one word carries status, epoch, misalignment and freshness.
const AGE_SHIFT: u32 = 18;
/// The age of a stream older than the stale threshold, or with no reading: the largest
/// value the 14 bits hold.
pub(super) const AGE_STALE: u16 = (1 << (32 - AGE_SHIFT)) - 1;
/// The stale threshold in age units: ages up to it are `0..=AGE_STEPS`.
pub(super) const AGE_STEPS: u16 = AGE_STALE - 1;

/// The coefficient set shared by an [`Updater`](super::Updater) and an
/// [`Applier`](super::Applier), behind a sequence number (a seqlock): odd while the updater
/// writes, even when the set is whole. Const-constructible, so it can live in a `static`
/// (except under `--cfg loom`, whose atomics are not). 32 bytes for 3 axes without a
/// misalignment stage (`MATRIX` 0), 68 with one (`MATRIX` 3).
#[derive(Debug)]
pub struct Published<const AXES: usize, const MATRIX: usize = 0> {
    /// Odd while a publication is being written; +2 per publication (wrapping: 2³¹
    /// publications, 68 years at 1 Hz, before a sequence repeats).
    pub(super) seq: AtomicU32,
    /// g0/K1, m/s per pulse (m/s² per LSB for samples).
    scale: [AtomicU32; AXES],
    /// The bias in the configured input's form: K0·g0·tick, m/s per tick, for pulse counts;
    /// K0·g0, m/s², for samples. The other form is never applied (the other entry returns
    /// zeros with [`Status::WRONG_INPUT`]), so it is not published.
    bias: [AtomicU32; AXES],
    /// Row-major misalignment matrix (valid when the flags have [`HAS_MISALIGN`]): `MATRIX`
    /// rows, none without a misalignment stage.
    misalign: [[AtomicU32; AXES]; MATRIX],
    /// Status bits (0–8), the epoch (9–16), [`HAS_MISALIGN`] (17), the oldest stream's age
    /// (18–31).
    pub(super) flags: AtomicU32,
}

impl<const AXES: usize, const MATRIX: usize> Default for Published<AXES, MATRIX> {
    fn default() -> Self {
        Self::new()
    }
}

/// One coefficient set as plain values: built by the updater at each publication, and
/// the applier's own copy of the last whole set it read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Set<const AXES: usize, const MATRIX: usize> {
    pub(super) scale: [f32; AXES],
    /// K0·g0·tick (m/s per tick) for pulse counts, K0·g0 (m/s²) for samples.
    pub(super) bias: [f32; AXES],
    /// Written only by a publication that [`Changes::matrix`]; read whenever the flags say
    /// the set has one.
    pub(super) misalign: Option<[[f32; AXES]; MATRIX]>,
    pub(super) status: Status,
    /// Age of the oldest stream's last good reading as of the latest reading's time, in
    /// `1/AGE_STEPS` of the stale threshold, rounded down; [`AGE_STALE`] when older than
    /// the threshold or while a stream has none. The applier's staleness countdown restarts from the
    /// threshold less this, so a stream that stops reporting is stale on time even while
    /// the others keep publishing.
    pub(super) age: u16,
    /// Counts (wrapping) the publications of good readings. The applier restarts its
    /// countdown when the epoch moved since its last copy, even if a later set (a
    /// rejection, a table load) superseded the good reading's before it was copied; other
    /// sets can only shorten the countdown. 256 good readings between two copies would
    /// alias (at 400 Hz and 1 Hz per sensor the applier copies every one): the countdown
    /// then only shortens, so the error is an early stale flag, never a late one.
    pub(super) epoch: u8,
}

impl<const AXES: usize, const MATRIX: usize> Set<AXES, MATRIX> {
    pub(super) const EMPTY: Self = Self {
        scale: [0.0; AXES],
        bias: [0.0; AXES],
        misalign: None,
        status: Status::empty(),
        age: AGE_STALE,
        epoch: 0,
    };
}

/// What a publication writes besides the flags word (status, epoch, age), which every
/// publication writes. The words it leaves alone keep the values of the set in force, which
/// are still right: a rejected reading changes no coefficient, and the matrix changes only
/// with the table. (Writing only the axis a reading serves, with a sensor per axis, was
/// measured too: the mask cost more instructions and flash than the stores and divisions it
/// skipped; see docs/measurements.md.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Changes {
    /// Every axis's scale and bias.
    pub(super) coefficients: bool,
    /// The matrix (and whether there is one), from [`Set::misalign`].
    pub(super) matrix: bool,
}

impl Changes {
    /// Everything: at construction and at each table.
    pub(super) const ALL: Self = Self { coefficients: true, matrix: true };
    /// The coefficients, not the matrix: a reading.
    pub(super) const COEFFICIENTS: Self = Self { coefficients: true, matrix: false };
    /// The flags word alone: a rejected or missed reading.
    pub(super) const FLAGS: Self = Self { coefficients: false, matrix: false };
}

/// A whole set as read by [`Published::read_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Snapshot<const AXES: usize, const MATRIX: usize> {
    /// The (even) sequence the set was published under.
    pub(super) seq: u32,
    pub(super) set: Set<AXES, MATRIX>,
}

#[cfg(not(loom))]
impl<const AXES: usize, const MATRIX: usize> Published<AXES, MATRIX> {
    /// Empty: every coefficient zero and no status until the first publication (the
    /// compensator publishes at construction).
    #[must_use]
    pub const fn new() -> Self {
        Self::starting_at(0)
    }

    /// Empty, with the sequence at `seq` (the tests start near `u32::MAX` to wrap it).
    const fn starting_at(seq: u32) -> Self {
        Self {
            seq: AtomicU32::new(seq),
            scale: [const { AtomicU32::new(0) }; AXES],
            bias: [const { AtomicU32::new(0) }; AXES],
            misalign: [const { [const { AtomicU32::new(0) }; AXES] }; MATRIX],
            flags: AtomicU32::new(0),
        }
    }
}

// loom's `AtomicU32::new` registers the atomic with the running model, so it is not `const`.
#[cfg(loom)]
impl<const AXES: usize, const MATRIX: usize> Published<AXES, MATRIX> {
    /// Empty: every coefficient zero and no status until the first publication (the
    /// compensator publishes at construction). Not `const` under loom.
    #[must_use]
    pub fn new() -> Self {
        Self::starting_at(0)
    }

    /// Empty, with the sequence at `seq` (the tests start near `u32::MAX` to wrap it).
    fn starting_at(seq: u32) -> Self {
        let zeros = || core::array::from_fn(|_| AtomicU32::new(0));
        Self {
            seq: AtomicU32::new(seq),
            scale: zeros(),
            bias: zeros(),
            misalign: core::array::from_fn(|_| zeros()),
            flags: AtomicU32::new(0),
        }
    }
}

impl<const AXES: usize, const MATRIX: usize> Published<AXES, MATRIX> {
    /// A word-for-word copy. Only for [`Compensator::clone`](super::Compensator): `&self` there means no split is
    /// alive, so no publication is in progress and the words are one whole set.
    pub(super) fn snapshot(&self) -> Self {
        let copy = |a: &AtomicU32| AtomicU32::new(a.load(Ordering::Relaxed));
        Self {
            seq: copy(&self.seq),
            scale: core::array::from_fn(|i| copy(&self.scale[i])),
            bias: core::array::from_fn(|i| copy(&self.bias[i])),
            misalign: core::array::from_fn(|r| core::array::from_fn(|c| copy(&self.misalign[r][c]))),
            flags: copy(&self.flags),
        }
    }

    /// Write what `changes` names of `set`, and its flags word (seqlock writer). `after_store`
    /// runs after every single store (a test hook that preempts the writer there; a no-op
    /// closure otherwise). Only the updater calls this: one writer at a time, so it may read
    /// back its own last flags word.
    pub(super) fn publish_with(&self, set: &Set<AXES, MATRIX>, changes: Changes, mut after_store: impl FnMut()) {
        let seq = self.seq.load(Ordering::Relaxed);
        self.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
        // The odd sequence is visible before any value changes: a reader's Acquire fence
        // after loading any value stored below makes its re-check see this odd sequence.
        #[cfg(not(qfa_mutant = "writer_no_release_fence"))]
        fence(Ordering::Release);
        after_store();
        if changes.coefficients {
            for i in 0..AXES {
                self.scale[i].store(set.scale[i].to_bits(), Ordering::Relaxed);
                after_store();
                self.bias[i].store(set.bias[i].to_bits(), Ordering::Relaxed);
                after_store();
            }
        }
        let mut flags = u32::from(set.status.bits())
            | (u32::from(set.epoch) << EPOCH_SHIFT)
            | (u32::from(set.age.min(AGE_STALE)) << AGE_SHIFT);
        if !changes.matrix {
            flags |= self.flags.load(Ordering::Relaxed) & HAS_MISALIGN;
        } else if let Some(m) = &set.misalign {
            for (dst, src) in self.misalign.iter().zip(m.iter()) {
                for (d, s) in dst.iter().zip(src.iter()) {
                    d.store(s.to_bits(), Ordering::Relaxed);
                    after_store();
                }
            }
            flags |= HAS_MISALIGN;
        }
        self.flags.store(flags, Ordering::Relaxed);
        after_store();
        // Release: every value above is visible to a reader that loads the even sequence.
        #[cfg(not(qfa_mutant = "writer_relaxed_even_store"))]
        self.seq.store(seq.wrapping_add(2), Ordering::Release);
        #[cfg(qfa_mutant = "writer_relaxed_even_store")]
        self.seq.store(seq.wrapping_add(2), Ordering::Relaxed);
        after_store();
    }

    /// Copy the set if it is whole (seqlock reader): `None` when the sequence is odd (a
    /// publication under way) or moved during the copy (the copy may mix two sets). Never
    /// waits. `mid` runs between the copy and the re-check (a test hook: the updater
    /// preempting the reader there; a no-op closure otherwise).
    #[inline(always)]
    pub(super) fn read_with(&self, mid: impl FnOnce()) -> Option<Snapshot<AXES, MATRIX>> {
        // Acquire: the values of the publication that made this sequence even are visible.
        #[cfg(not(qfa_mutant = "reader_relaxed_seq_load"))]
        let seq = self.seq.load(Ordering::Acquire);
        #[cfg(qfa_mutant = "reader_relaxed_seq_load")]
        let seq = self.seq.load(Ordering::Relaxed);
        #[cfg(not(qfa_mutant = "reader_accepts_odd"))]
        if seq & 1 == 1 {
            return None;
        }
        let load = |a: &AtomicU32| f32::from_bits(a.load(Ordering::Relaxed));
        let flags = self.flags.load(Ordering::Relaxed);
        let set = Set {
            scale: core::array::from_fn(|i| load(&self.scale[i])),
            bias: core::array::from_fn(|i| load(&self.bias[i])),
            misalign: (flags & HAS_MISALIGN != 0)
                .then(|| core::array::from_fn(|r| core::array::from_fn(|c| load(&self.misalign[r][c])))),
            status: Status::from_bits_retain((flags & STATUS_BITS) as u16),
            age: (flags >> AGE_SHIFT) as u16,
            epoch: (flags >> EPOCH_SHIFT) as u8,
        };
        mid();
        // The loads above happen before the re-check, and a value of a later publication
        // among them makes the re-check see that publication's odd sequence.
        #[cfg(not(qfa_mutant = "reader_no_acquire_fence"))]
        fence(Ordering::Acquire);
        #[cfg(not(qfa_mutant = "reader_no_recheck"))]
        if self.seq.load(Ordering::Relaxed) != seq {
            return None;
        }
        Some(Snapshot { seq, set })
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    /// Needs `Published::new` to be `const`, as a board's `static` does.
    static SHARED: Published<3> = Published::new();
    static SHARED_WITH_MATRIX: Published<3, 3> = Published::new();

    #[test]
    fn a_published_set_is_a_static_of_32_bytes_for_3_axes_and_68_with_a_matrix() {
        assert_eq!(core::mem::size_of_val(&SHARED), 32);
        assert_eq!(core::mem::size_of_val(&SHARED_WITH_MATRIX), 68);
        let empty = Set { age: 0, ..Set::EMPTY };
        assert_eq!(SHARED.read_with(|| {}).map(|s| (s.seq, s.set)), Some((0, empty)));
    }
}

/// The loom model of the seqlock: `RUSTFLAGS="--cfg loom"`, run by `cargo xtask loom` (with
/// the mutants) and `cargo xtask test` (clean only).
///
/// The main thread makes publication 0, starts a writer thread that makes publications
/// 1..=`publications`, reads twice meanwhile, joins the writer and reads once more. Every
/// value of publication `i` is derived from `i`, so a copy that mixes two publications, or
/// whose sequence names another publication than its values, fails an assertion.
///
/// One axis and no misalignment matrix: three words per set (scale, bias, flags), so a
/// copy has three Relaxed loads that can each come from a different publication. The 1×1
/// matrix would be a fourth word loaded and stored the same way; it multiplies the
/// executions by about 9 (measured as 785 362 against 89 453 for one publication, before the
/// flags word carried the age and the epoch, and before the set had one bias) and checks
/// nothing the other words do not. Every publication here writes every word
/// ([`Changes::ALL`]): one that writes fewer ([`Changes::COEFFICIENTS`], [`Changes::FLAGS`]) makes a
/// subset of the same stores between the same sequence stores and fences, which is what the
/// argument rests on.
#[cfg(all(test, loom))]
mod model {
    use super::*;
    use loom::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering as StdOrdering};

    /// Reads by the main thread while the writer runs: 2, so the order of two accepted
    /// copies is checked.
    const READS: usize = 2;

    /// Publication `i`: word `w` of the set holds `8·i + w` (exact in f32), the status bits
    /// hold `i`, the age is `i + 5` units and the epoch `i + 1`.
    fn set_of(i: u32) -> Set<1, 0> {
        let word = |w: u32| (8 * i + w) as f32;
        Set {
            scale: [word(1)],
            bias: [word(2)],
            misalign: None,
            status: Status::from_bits_retain(i as u16 & 0xFF),
            age: i as u16 + 5,
            epoch: i as u8 + 1,
        }
    }

    /// The publication a copy comes from; panics unless every word, the status, the age
    /// and the sequence name the same one.
    fn publication_of(start: u32, s: &Snapshot<1, 0>) -> u32 {
        let i = u32::from(s.set.status.bits());
        assert_eq!(s.set, set_of(i), "copy mixes publications: status says {i}, {s:?}");
        // Publication i leaves the sequence at start + 2·(i + 1).
        assert_eq!(s.seq.wrapping_sub(start), 2 * (i + 1), "sequence names another publication: {s:?}");
        i
    }

    /// Every execution loom finds of one writer making `publications` after publication 0,
    /// and one reader, with the sequence starting at `start` and at most `preemptions`
    /// preemptions (`None`: no bound, every execution).
    fn check(start: u32, publications: u32, preemptions: Option<usize>) {
        // A std counter: loom's primitives exist only inside the model.
        let executions = std::sync::Arc::new(AtomicUsize::new(0));
        let counter = executions.clone();
        let mut builder = loom::model::Builder::new();
        builder.preemption_bound = preemptions;
        // No cap from the environment: LOOM_MAX_PERMUTATIONS or LOOM_MAX_DURATION would end
        // the search early, and the test would pass on what it had seen.
        builder.max_permutations = None;
        builder.max_duration = None;
        builder.check(move || {
            counter.fetch_add(1, StdOrdering::Relaxed);
            let p = Arc::new(Published::<1>::starting_at(start));
            p.publish_with(&set_of(0), Changes::ALL, || {});
            let writer = {
                let p = p.clone();
                loom::thread::spawn(move || {
                    for i in 1..=publications {
                        p.publish_with(&set_of(i), Changes::ALL, || {});
                    }
                })
            };
            let mut last = 0;
            for _ in 0..READS {
                if let Some(s) = p.read_with(|| {}) {
                    let i = publication_of(start, &s);
                    assert!(i >= last, "went back from publication {last} to {i}");
                    last = i;
                }
            }
            writer.join().unwrap();
            // The writer has stopped: the read succeeds and gives its last publication.
            let s = p.read_with(|| {}).expect("no publication under way, yet the read failed");
            assert_eq!(publication_of(start, &s), publications);
        });
        let n = executions.load(StdOrdering::Relaxed);
        println!("seqlock model: sequence from {start:#010x}, {publications} publication(s), bound {preemptions:?}: {n} executions");
    }

    /// One publication against two reads, no preemption bound: every execution (231 252).
    #[test]
    fn one_publication_every_execution() {
        check(0, 1, None);
    }

    /// The same with the sequence wrapping during the writer's publication: odd `u32::MAX`,
    /// then even 0.
    #[test]
    fn one_publication_every_execution_across_the_sequence_wrap() {
        check(u32::MAX - 3, 1, None);
    }

    /// Two publications (a read can straddle both), at most 3 preemptions: 165 088
    /// executions (a bound of 5 gave 939 864 with the earlier flags word, 17 times the time). The sequence's 7 stores are loom's
    /// whole history per atomic (`MAX_ATOMIC_HISTORY` in loom 0.7), so no store a load
    /// could return is forgotten.
    #[test]
    fn two_publications_up_to_three_preemptions() {
        check(0, 2, Some(3));
    }
}

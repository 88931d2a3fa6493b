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

use core::sync::atomic::{fence, AtomicU32, Ordering};

use super::Status;

/// Flag in a published flags word: the set has a misalignment matrix.
pub(super) const HAS_MISALIGN: u32 = 1 << 16;
/// The good-sample count sits in the flags word's top bits (wrapping), so one word carries
/// status, misalignment and freshness.
pub(super) const COUNT_SHIFT: u32 = 17;

/// The coefficient set shared by an [`Updater`](super::Updater) and an
/// [`Applier`](super::Applier), behind a sequence number (a seqlock): odd while the updater
/// writes, even when the set is whole. Const-constructible, so it can live in a `static`.
/// 80 bytes for 3 axes.
#[derive(Debug)]
pub struct Published<const AXES: usize> {
    /// Odd while a publication is being written; +2 per publication (wrapping: 2³¹
    /// publications, 68 years at 1 Hz, before a sequence repeats).
    pub(super) seq: AtomicU32,
    /// g0/K1, m/s per pulse (m/s² per LSB for samples).
    scale: [AtomicU32; AXES],
    /// K0·g0·tick, m/s per tick.
    bias_tick: [AtomicU32; AXES],
    /// K0·g0, m/s².
    bias_acc: [AtomicU32; AXES],
    /// Row-major misalignment matrix (valid when the flags have [`HAS_MISALIGN`]).
    misalign: [[AtomicU32; AXES]; AXES],
    /// Status bits (low 16), [`HAS_MISALIGN`], good-sample count from [`COUNT_SHIFT`] up.
    pub(super) flags: AtomicU32,
}

impl<const AXES: usize> Default for Published<AXES> {
    fn default() -> Self {
        Self::new()
    }
}

/// One coefficient set as plain values: built by the updater at each publication, and
/// the applier's own copy of the last whole set it read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Set<const AXES: usize> {
    pub(super) scale: [f32; AXES],
    pub(super) bias_tick: [f32; AXES],
    pub(super) bias_acc: [f32; AXES],
    pub(super) misalign: Option<[[f32; AXES]; AXES]>,
    pub(super) status: Status,
}

impl<const AXES: usize> Set<AXES> {
    pub(super) const EMPTY: Self = Self {
        scale: [0.0; AXES],
        bias_tick: [0.0; AXES],
        bias_acc: [0.0; AXES],
        misalign: None,
        status: Status::empty(),
    };
}

/// A whole set as read by [`Published::read_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Snapshot<const AXES: usize> {
    /// The (even) sequence the set was published under.
    pub(super) seq: u32,
    pub(super) set: Set<AXES>,
    /// Good-sample count carried by the set's flags word (wrapping, 15 bits).
    pub(super) count: u32,
}

impl<const AXES: usize> Published<AXES> {
    /// Empty: every coefficient zero and no status until the first publication (the
    /// compensator publishes at construction).
    #[must_use]
    pub const fn new() -> Self {
        Self {
            seq: AtomicU32::new(0),
            scale: [const { AtomicU32::new(0) }; AXES],
            bias_tick: [const { AtomicU32::new(0) }; AXES],
            bias_acc: [const { AtomicU32::new(0) }; AXES],
            misalign: [const { [const { AtomicU32::new(0) }; AXES] }; AXES],
            flags: AtomicU32::new(0),
        }
    }

    /// Write `set` (seqlock writer); `good_sample` advances the good-sample count.
    /// `after_store` runs after every single store (a test hook that preempts the writer
    /// there; a no-op closure otherwise). Only the updater calls this: one writer at a time.
    pub(super) fn publish_with(&self, set: &Set<AXES>, good_sample: bool, mut after_store: impl FnMut()) {
        let seq = self.seq.load(Ordering::Relaxed);
        self.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
        // The odd sequence is visible before any value changes: a reader's Acquire fence
        // after loading any value stored below makes its re-check see this odd sequence.
        fence(Ordering::Release);
        after_store();
        for i in 0..AXES {
            self.scale[i].store(set.scale[i].to_bits(), Ordering::Relaxed);
            after_store();
            self.bias_tick[i].store(set.bias_tick[i].to_bits(), Ordering::Relaxed);
            after_store();
            self.bias_acc[i].store(set.bias_acc[i].to_bits(), Ordering::Relaxed);
            after_store();
        }
        let count = (self.flags.load(Ordering::Relaxed) >> COUNT_SHIFT).wrapping_add(u32::from(good_sample));
        let mut flags = u32::from(set.status.bits()) | (count << COUNT_SHIFT);
        if let Some(m) = &set.misalign {
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
        self.seq.store(seq.wrapping_add(2), Ordering::Release);
        after_store();
    }

    /// Copy the set if it is whole (seqlock reader): `None` when the sequence is odd (a
    /// publication under way) or moved during the copy (the copy may mix two sets). Never
    /// waits. `mid` runs between the copy and the re-check (a test hook: the updater
    /// preempting the reader there; a no-op closure otherwise).
    #[inline(always)]
    pub(super) fn read_with(&self, mid: impl FnOnce()) -> Option<Snapshot<AXES>> {
        // Acquire: the values of the publication that made this sequence even are visible.
        let seq = self.seq.load(Ordering::Acquire);
        if seq & 1 == 1 {
            return None;
        }
        let load = |a: &AtomicU32| f32::from_bits(a.load(Ordering::Relaxed));
        let flags = self.flags.load(Ordering::Relaxed);
        let set = Set {
            scale: core::array::from_fn(|i| load(&self.scale[i])),
            bias_tick: core::array::from_fn(|i| load(&self.bias_tick[i])),
            bias_acc: core::array::from_fn(|i| load(&self.bias_acc[i])),
            misalign: (flags & HAS_MISALIGN != 0)
                .then(|| core::array::from_fn(|r| core::array::from_fn(|c| load(&self.misalign[r][c])))),
            status: Status::from_bits_retain(flags as u16),
        };
        mid();
        // The loads above happen before the re-check, and a value of a later publication
        // among them makes the re-check see that publication's odd sequence.
        fence(Ordering::Acquire);
        if self.seq.load(Ordering::Relaxed) != seq {
            return None;
        }
        Some(Snapshot { seq, set, count: flags >> COUNT_SHIFT })
    }
}

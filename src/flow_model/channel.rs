//! The shared channel and hanging filament as a FIFO of material slugs in plug flow: what
//! enters pushes the oldest out, and the per-material volume inside the channel (which sets
//! its resistance) is kept exactly in fixed point. Flow rates are `mod.rs`'s business.

use crate::vol::Vol;
use heapless::Deque;

pub use crate::capacity::SLUG_CAPACITY;

/// One run of a single material, starting at entry coordinate `start`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slug {
    /// Inlet index of the material.
    pub material: u8,
    /// Cumulative entered volume at which this slug began entering.
    pub start: Vol,
}

/// Coordinates: `entered` counts every volume that ever entered. The channel occupies
/// `[entered - v_channel, entered)`, the hanging filament below it
/// `[entered - v_transit, entered - v_channel)`; below that it lies on the plate.
#[derive(Clone, Debug)]
pub struct Channel<const N: usize> {
    slugs: Deque<Slug, SLUG_CAPACITY>,
    entered: Vol,
    v_channel: Vol,
    v_transit: Vol,
    /// Volume of each material inside the channel (not the hanging filament).
    in_channel: [Vol; N],
    /// Index of the slug at the channel exit.
    exit_idx: usize,
    /// An `advance` since `clear_crossed` crossed a slug start at the exit or the plate
    /// (took its slow path).
    crossed: bool,
    /// Entered volume up to which no slug start reaches the exit or the plate: below it
    /// `advance` only moves volume (kept by `refresh` whenever the slugs change).
    clear_until: Vol,
    /// Materials entering, at the exit and landing (cached with `clear_until`: the
    /// tick reads them every cycle, and each read of the deque is a split of its ring).
    newest_m: u8,
    exit_m: u8,
    landing_m: u8,
    /// Slugs held (cached with the materials: every report and ramped frame reads it).
    count: usize,
}

/// The channel could not take another slug.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelFull;

impl<const N: usize> Channel<N> {
    /// A channel of no volume holding nothing; `refill` gives it its volumes. A constant
    /// constructor, so a model can be built at compile time.
    pub const fn empty() -> Self {
        Channel {
            slugs: Deque::new(),
            entered: Vol::ZERO,
            v_channel: Vol::ZERO,
            v_transit: Vol::ZERO,
            in_channel: [Vol::ZERO; N],
            exit_idx: 0,
            crossed: false,
            clear_until: Vol::ZERO,
            newest_m: 0,
            exit_m: 0,
            landing_m: 0,
            count: 0,
        }
    }

    /// A channel and filament full of `material`.
    pub fn full_of(material: u8, v_channel: Vol, v_hang: Vol) -> Self {
        let mut c = Self::empty();
        c.refill(material, v_channel, v_hang);
        c
    }

    /// Makes this the channel of `full_of(material, v_channel, v_hang)`, in place.
    pub fn refill(&mut self, material: u8, v_channel: Vol, v_hang: Vol) {
        let v_transit = v_channel + v_hang;
        self.slugs.clear();
        let _ = self.slugs.push_back(Slug {
            material,
            start: Vol::ZERO,
        });
        self.in_channel = [Vol::ZERO; N];
        if let Some(v) = self.in_channel.get_mut(material as usize) {
            *v = v_channel;
        }
        self.entered = v_transit;
        self.v_channel = v_channel;
        self.v_transit = v_transit;
        self.exit_idx = 0;
        self.crossed = false;
        self.clear_until = Vol::ZERO;
        self.newest_m = material;
        self.exit_m = material;
        self.landing_m = material;
        self.refresh();
    }

    /// Works out the fast path's limits after the slugs changed.
    fn refresh(&mut self) {
        let exit_at = self
            .slug(self.exit_idx + 1)
            .map_or(Vol(i64::MAX), |s| s.start + self.v_channel);
        let land_at = self
            .slug(1)
            .map_or(Vol(i64::MAX), |s| s.start + self.v_transit);
        self.clear_until = exit_at.min(land_at);
        self.newest_m = self.slugs.back().map(|s| s.material).unwrap_or(0);
        self.exit_m = self.slug(self.exit_idx).map(|s| s.material).unwrap_or(0);
        self.landing_m = self.slugs.front().map(|s| s.material).unwrap_or(0);
        self.count = self.slugs.len();
    }

    /// The i-th slug from the plate end, in O(1).
    #[inline]
    fn slug(&self, i: usize) -> Option<&Slug> {
        let (a, b) = self.slugs.as_slices();
        if i < a.len() {
            a.get(i)
        } else {
            b.get(i - a.len())
        }
    }

    /// Volume of each material inside the channel.
    pub fn in_channel(&self) -> &[Vol; N] {
        &self.in_channel
    }
    /// Material entering now (the newest slug's).
    #[inline]
    pub fn newest(&self) -> u8 {
        self.newest_m
    }
    /// Material at the channel exit (nozzle tip).
    #[inline]
    pub fn at_exit(&self) -> u8 {
        self.exit_m
    }
    /// Material landing on the plate now.
    #[inline]
    pub fn landing(&self) -> u8 {
        self.landing_m
    }
    /// True when an `advance` since `clear_crossed` crossed a slug start at the exit or
    /// the plate.
    pub fn crossed(&self) -> bool {
        self.crossed
    }
    /// Starts a new count for `crossed` (the flow model does, once per cycle).
    pub fn clear_crossed(&mut self) {
        self.crossed = false;
    }
    /// Cumulative entered volume.
    pub fn entered(&self) -> Vol {
        self.entered
    }
    /// Slugs from the plate end to the junction.
    pub fn slugs(&self) -> impl Iterator<Item = &Slug> {
        self.slugs.iter()
    }
    /// Number of slugs held.
    #[inline]
    pub fn len(&self) -> usize {
        self.count
    }
    /// Never true: the channel always holds at least one slug.
    pub fn is_empty(&self) -> bool {
        self.slugs.is_empty()
    }

    /// True when `dv` more entering moves no slug start past the exit or onto the plate:
    /// `advance` takes its fast path, and `exit_room` (if any) is more than `dv`.
    #[inline]
    pub fn clear_for(&self, dv: Vol) -> bool {
        self.entered + dv < self.clear_until
    }

    /// Volume that can still pass the channel exit before the material there changes,
    /// or `None` if the exit is inside the newest slug.
    pub fn exit_room(&self) -> Option<Vol> {
        let exit = self.entered - self.v_channel;
        self.slug(self.exit_idx + 1).map(|next| next.start - exit)
    }

    /// Upcoming changes at the exit: (mm^3 from the exit to the change, material after),
    /// nearest first, at most `out.len()`. Returns how many were written.
    pub fn exit_changes<R: crate::real::Real>(&self, out: &mut [(R, u8)]) -> usize {
        let exit = self.entered - self.v_channel;
        // The ring's two slices, past the exit's slug: one split of the deque (its
        // iterator's `skip` stepped slug by slug through an out-of-line `nth`).
        let skip = self.exit_idx + 1;
        let (a, b) = self.slugs.as_slices();
        let (a, b) = match a.get(skip..) {
            Some(rest) => (rest, b),
            None => (&[][..], b.get(skip - a.len()..).unwrap_or(&[])),
        };
        let mut n = 0;
        for (o, s) in out.iter_mut().zip(a.iter().chain(b)) {
            *o = ((s.start - exit).mm3(), s.material);
            n += 1;
        }
        n
    }

    /// Starts a new slug if `material` differs from the one entering. Inlined: nearly
    /// every cycle feeds the material already entering, one compare.
    #[inline]
    pub fn feed(&mut self, material: u8) -> Result<(), ChannelFull> {
        if self.newest_m == material {
            return Ok(());
        }
        self.feed_new(material)
    }

    /// `feed` of a material other than the one entering: a new slug.
    #[inline(never)]
    fn feed_new(&mut self, material: u8) -> Result<(), ChannelFull> {
        self.slugs
            .push_back(Slug {
                material,
                start: self.entered,
            })
            .map_err(|_| ChannelFull)?;
        self.refresh();
        Ok(())
    }

    /// Moves `dv` of the newest slug's material in at the junction; as much leaves the
    /// channel into the filament and lands on the plate. Returns how many material changes
    /// landed on the plate during this advance.
    /// Inlined: the fast path is a few instructions, the slow one out of line.
    #[inline]
    pub fn advance(&mut self, dv: Vol) -> u32 {
        if dv.0 <= 0 {
            return 0;
        }
        // Fast path, nearly every cycle: no slug start crosses the exit (its start stays
        // above `entered - v_channel`) or lands (above `entered - v_transit`).
        if self.entered + dv < self.clear_until {
            let (newest, here) = (self.newest_m as usize, self.exit_m as usize);
            if newest != here {
                if let Some(v) = self.in_channel.get_mut(newest) {
                    *v += dv;
                }
                if let Some(v) = self.in_channel.get_mut(here) {
                    *v -= dv;
                }
            }
            self.entered += dv;
            return 0;
        }
        self.advance_crossing(dv)
    }

    /// `advance` of `dv > 0` that moves a slug start past the exit or onto the plate.
    #[inline(never)]
    fn advance_crossing(&mut self, dv: Vol) -> u32 {
        self.crossed = true;
        let newest = self.newest() as usize;
        if let Some(v) = self.in_channel.get_mut(newest) {
            *v += dv;
        }
        // Channel exit moves from `exit` to `exit + dv`, crossing slug starts.
        let mut exit = self.entered - self.v_channel;
        let exit_end = exit + dv;
        loop {
            let here = self
                .slug(self.exit_idx)
                .map(|s| s.material as usize)
                .unwrap_or(0);
            let next_start = self.slug(self.exit_idx + 1).map(|s| s.start);
            // A slug that starts exactly where the exit stops is the exit's slug from now on.
            let (upto, crossed) = match next_start {
                Some(ns) if ns <= exit_end => (ns, true),
                _ => (exit_end, false),
            };
            if let Some(v) = self.in_channel.get_mut(here) {
                *v -= upto - exit;
            }
            exit = upto;
            if crossed {
                self.exit_idx += 1;
            } else {
                break;
            }
        }
        self.entered += dv;
        // Landing: drop slugs wholly on the plate.
        let landed_to = self.entered - self.v_transit;
        let mut changes = 0;
        while self.slugs.len() > 1 {
            let second = self.slug(1).map(|s| s.start).unwrap_or(Vol(i64::MAX));
            if second <= landed_to {
                self.slugs.pop_front();
                self.exit_idx = self.exit_idx.saturating_sub(1);
                changes += 1;
            } else {
                break;
            }
        }
        self.refresh();
        changes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plug_flow_moves_slugs_through_channel_and_filament() {
        let mut c: Channel<4> = Channel::full_of(0, Vol(1000), Vol(200));
        assert_eq!(c.in_channel()[0], Vol(1000));
        c.feed(1).unwrap();
        assert_eq!(c.advance(Vol(300)), 0);
        assert_eq!(c.in_channel()[0], Vol(700));
        assert_eq!(c.in_channel()[1], Vol(300));
        assert_eq!(c.exit_room(), Some(Vol(700)));
        c.feed(2).unwrap();
        c.advance(Vol(100));
        assert_eq!(c.in_channel(), &[Vol(600), Vol(300), Vol(100), Vol(0)]);
        // Material 1 reaches the exit after 600 more, the plate after 200 beyond that.
        c.advance(Vol(650));
        assert_eq!(c.at_exit(), 1);
        assert_eq!(c.landing(), 0);
        assert_eq!(c.advance(Vol(200)), 1);
        assert_eq!(c.landing(), 1);
        let total: i64 = c.in_channel().iter().map(|v| v.0).sum();
        assert_eq!(total, 1000);
    }

    #[test]
    fn a_slug_shorter_than_one_advance_is_crossed_in_one_step() {
        let mut c: Channel<4> = Channel::full_of(0, Vol(1000), Vol(0));
        for m in [1u8, 2, 3, 0] {
            c.feed(m).unwrap();
            c.advance(Vol(10));
        }
        // Push everything out in one go: 1040 entered since; slugs 0(960)|1|2|3|0(10) ...
        c.feed(1).unwrap();
        let changes = c.advance(Vol(2000));
        assert_eq!(changes, 5);
        assert_eq!(c.in_channel()[1], Vol(1000));
        assert_eq!(c.len(), 1);
    }

    #[test]
    fn an_advance_ending_exactly_on_a_slug_start_moves_the_exit_into_it() {
        let mut c: Channel<4> = Channel::full_of(0, Vol(1000), Vol(0));
        c.feed(1).unwrap();
        c.advance(Vol(400));
        assert_eq!(c.exit_room(), Some(Vol(600)));
        c.advance(Vol(600));
        assert_eq!(c.at_exit(), 1);
        assert_eq!(c.exit_room(), None);
        assert_eq!(c.in_channel()[0], Vol(0));
    }

    #[test]
    fn capacity_is_reported_not_panicked() {
        let mut c: Channel<2> = Channel::full_of(0, Vol(1_000_000), Vol(0));
        let mut full = false;
        for i in 0..200 {
            if c.feed((i % 2) as u8).is_err() {
                full = true;
                break;
            }
            c.advance(Vol(1));
        }
        assert!(full);
    }
}

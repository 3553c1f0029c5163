//! The plan: job commands turned into plan items (print segments with their fillets,
//! travels, dwells, the end), the material boundaries the valves switch at and the
//! volumes where beads end. Stops at the queues: following them is `drive`'s and
//! `valves`'.

use super::{um, Executor};
use crate::command::{Command, CommandError, MAX_DWELL_MS, MAX_SEGMENT_UM};
use crate::motion::{fillet, Fillet, V2};
use crate::outputs::Axis;
use crate::real::Real;
use crate::state::Fault;
use crate::vol::Vol;

/// A finalised print segment: the straight part, then the fillet into the next segment.
#[derive(Clone, Copy, Debug)]
pub(super) struct Seg<R> {
    pub(super) material: u8,
    pub(super) start: V2<R>,
    pub(super) dir: V2<R>,
    pub(super) len: R,
    pub(super) fillet: Option<Fillet<R>>,
    pub(super) u_start: Vol,
    pub(super) u_arc: Vol,
    pub(super) u_end: Vol,
    pub(super) last: bool,
    pub(super) index: u32,
    /// 1 / the section this segment is laid at (`Command::Section`; a stair of a change
    /// of section mid-bead, `crate::section_taper`), 1/mm^2: only the inverse, so that a
    /// segment (copied as each bead starts) grows by one word.
    pub(super) inv_s: R,
}

#[derive(Clone, Copy, Debug)]
pub(super) enum Item<R> {
    Seg(Seg<R>),
    Travel { to: [R; 3], index: u32 },
    Dwell { cycles: u64, index: u32 },
    End { index: u32 },
}

/// The newest print segment, not final until the next command shows how it ends.
#[derive(Clone, Copy, Debug)]
pub(super) struct Open<R> {
    material: u8,
    from: V2<R>,
    to: V2<R>,
    dir: V2<R>,
    length: R,
    /// Tangent length taken at the start by the previous segment's fillet.
    t_start: R,
    u_start: Vol,
    index: u32,
}

impl<R: Real, const N: usize> Executor<R, N> {
    pub(super) fn check_limits(&self, p: [R; 3]) -> Result<(), Fault> {
        for (a, axis) in Axis::ALL.iter().enumerate() {
            if !(p[a] >= self.machine.motion.min_mm[a] && p[a] <= self.machine.motion.max_mm[a]) {
                return Err(Fault::Limit { axis: *axis });
            }
        }
        Ok(())
    }

    /// Turns a command into plan items and boundaries.
    pub(super) fn plan_command(&mut self, cmd: Command) -> Result<(), Fault> {
        if self.ended {
            return Err(Fault::InvalidCommand(CommandError::AfterEnd));
        }
        let index = self.commands;
        match cmd {
            Command::Print { dx, dy, material } => {
                if material as usize >= self.machine.inlet_count() {
                    return Err(Fault::InvalidCommand(CommandError::NoSuchInlet {
                        material,
                        inlets: self.machine.inlet_count() as u8,
                    }));
                }
                let (dxl, dyl) = (dx as i64, dy as i64);
                if dxl.abs() > MAX_SEGMENT_UM || dyl.abs() > MAX_SEGMENT_UM {
                    return Err(Fault::InvalidCommand(CommandError::SegmentTooLong));
                }
                let from_um = self.design_um;
                let to_um = [
                    sat_i32(from_um[0] as i64 + dxl),
                    sat_i32(from_um[1] as i64 + dyl),
                    from_um[2],
                ];
                let to3 = [um(to_um[0]), um(to_um[1]), um(to_um[2])];
                self.check_limits(to3)?;
                if dx == 0 && dy == 0 {
                    return Ok(());
                }
                self.design_um = to_um;
                let from = [um::<R>(from_um[0]), um(from_um[1])];
                let to = [to3[0], to3[1]];
                let length = R::of(((dxl * dxl + dyl * dyl) as f64).sqrt() * 1e-3);
                let dir = [(to[0] - from[0]) / length, (to[1] - from[1]) / length];
                let (t_start, u_start) = match self.open.take() {
                    Some(prev) => {
                        let (seg, t, corner_mid) = self.finalise(prev, Some((dir, length)));
                        let _ = self.plan.push_back(Item::Seg(seg));
                        // A section asked since the segment before: this one starts the
                        // staircase to it (`crate::section_taper`).
                        if self.taper.target() != self.plan_s.1 {
                            self.start_taper();
                        }
                        if seg.material != material {
                            let _ = self.boundaries.push_back((corner_mid, material));
                        }
                        self.last_final = Some((seg.material, seg.u_end));
                        self.known_to = Some(seg.u_end);
                        (t, seg.u_end)
                    }
                    None => {
                        // A bead starts at its section at once (its speed rises from rest).
                        self.taper.set(self.plan_s.0, self.plan_s.1);
                        let (m, u) = self.last_final.unwrap_or((material, Vol::ZERO));
                        if m != material {
                            let _ = self.boundaries.push_back((u, material));
                        }
                        (R::ZERO, u)
                    }
                };
                self.open = Some(Open {
                    material,
                    from,
                    to,
                    dir,
                    length,
                    t_start,
                    u_start,
                    index,
                });
                Ok(())
            }
            Command::Travel { x, y, z } => {
                let to = [um(x), um(y), um(z)];
                self.check_limits(to)?;
                self.close_bead();
                self.design_um = [x, y, z];
                let _ = self.plan.push_back(Item::Travel { to, index });
                Ok(())
            }
            Command::Layer { z } => {
                let [x, y, _] = self.design_um;
                let to = [um(x), um(y), um(z)];
                self.check_limits(to)?;
                self.close_bead();
                self.design_um[2] = z;
                let _ = self.plan.push_back(Item::Travel { to, index });
                Ok(())
            }
            Command::Dwell { ms } => {
                if ms > MAX_DWELL_MS {
                    return Err(Fault::InvalidCommand(CommandError::DwellTooLong { ms }));
                }
                self.close_bead();
                let cycles = (ms as u64 * 1000).div_ceil(self.machine.period_us as u64);
                let _ = self.plan.push_back(Item::Dwell { cycles, index });
                Ok(())
            }
            Command::Section { um2 } => {
                // Between beads it holds from the next bead's start; inside a bead, from
                // the next print segment's start, reached over `crate::section_taper`'s
                // staircase (a step of the head's speed at constant flow).
                let (min_um2, max_um2) = self.section_um2;
                if um2 < min_um2 || um2 > max_um2 {
                    return Err(Fault::InvalidCommand(CommandError::SectionOutOfRange {
                        um2,
                        min_um2,
                        max_um2,
                    }));
                }
                let s = R::of(um2 as f64 * 1e-6);
                self.plan_s = (s, R::ONE / s);
                Ok(())
            }
            Command::End => {
                self.close_bead();
                let _ = self.plan.push_back(Item::End { index });
                self.ended = true;
                self.known_to = None;
                Ok(())
            }
        }
    }

    /// Finalises the open segment as the last of its bead.
    fn close_bead(&mut self) {
        if let Some(prev) = self.open.take() {
            let (seg, _, _) = self.finalise(prev, None);
            let _ = self.plan.push_back(Item::Seg(seg));
            let _ = self.ends.push_back(seg.u_end);
            self.last_final = Some((seg.material, seg.u_end));
            self.known_to = Some(seg.u_end);
            // A change under way ends with its bead (the next starts at its section).
            self.taper.set(self.plan_s.0, self.plan_s.1);
        }
    }

    /// Starts the staircase to the section asked, at the flow's top (`v_flow_max` through
    /// the config's section) and the lower X/Y limit.
    fn start_taper(&mut self) {
        let m = &self.machine;
        let q_max = m.v_flow_max * m.bead_area;
        let a = m.motion.max_accel[0].min(m.motion.max_accel[1]);
        self.taper.start(self.plan_s.0, self.plan_s.1, q_max, a);
    }

    /// Plan places a command may take beyond the one `room` keeps: a segment laid on a
    /// section's staircase is a plan item a stair.
    pub(super) fn taper_room(&self) -> usize {
        if self.taper.active() {
            crate::section_taper::TAPER_STAIRS
        } else {
            0
        }
    }

    /// Fixes an open segment's end: the fillet into `next` (direction, length), or the
    /// bead's end. Returns the segment, the tangent length the next one starts with and
    /// the middle of its fillet as plan volume (where a change of material goes); the
    /// lengths of it on a section's earlier stairs (`crate::section_taper`), fillet
    /// included, go into the plan first, a segment each.
    fn finalise(&mut self, o: Open<R>, next: Option<(V2<R>, R)>) -> (Seg<R>, R, Vol) {
        let f = next.and_then(|(d2, l2)| {
            // This segment's fillet may use all of it that the previous fillet left; the next
            // segment keeps half for its own far end.
            let max_t = (o.length - o.t_start).min(l2 * R::HALF);
            fillet(o.to, o.dir, d2, self.machine.corner_radius, max_t)
        });
        let t_end = f.map(|f| f.tangent).unwrap_or(R::ZERO);
        let len = (o.length - o.t_start - t_end).max(R::ZERO);
        let start = [
            o.from[0] + o.dir[0] * o.t_start,
            o.from[1] + o.dir[1] * o.t_start,
        ];
        let at = |x: R| [start[0] + o.dir[0] * x, start[1] + o.dir[1] * x];
        let fl = f.map(|f| f.length()).unwrap_or(R::ZERO);
        let total = len + fl;
        // Bead from `a` to `b` along the straight part and on round its fillet, laid at
        // section `s` (inverse `inv_s`) from plan volume `u`.
        let piece = |a: R, b: R, u: Vol, (s, inv_s): (R, R)| {
            let (sa, sb) = (a.min(len), b.min(len));
            let (fa, fb) = ((a - len).max(R::ZERO), (b - len).max(R::ZERO));
            let (arc, arc_len) = match f {
                // The whole fillet as it is (bitwise: no change without a staircase).
                Some(f) if fa == R::ZERO && b >= total => (Some(f), fl),
                Some(f) if fb > fa => (Some(sub_fillet(f, fa, fb)), fb - fa),
                _ => (None, R::ZERO),
            };
            let u_arc = u + Vol::from_mm3((sb - sa) * s);
            let u_end = u_arc + arc.map(|_| Vol::from_mm3(arc_len * s)).unwrap_or(Vol::ZERO);
            Seg {
                material: o.material,
                start: at(sa),
                dir: o.dir,
                len: sb - sa,
                fillet: arc,
                u_start: u,
                u_arc,
                u_end,
                last: false,
                index: o.index,
                inv_s,
            }
        };
        let mut stair = self.taper.now();
        let (mut x, mut u) = (R::ZERO, o.u_start);
        // Where the fillet starts, as plan volume.
        let mut u_corner = None;
        // At most `TAPER_STAIRS` rounds (`Taper::take`): the staircase goes on round the
        // fillet, which is cut at each stair as the straight part is.
        while let Some(l) = self.taper.take(total - x) {
            let p = piece(x, x + l, u, stair);
            if x <= len && x + l >= len {
                u_corner = Some(p.u_arc);
            }
            let _ = self.plan.push_back(Item::Seg(p));
            (x, u) = (x + l, p.u_end);
            stair = self.taper.now();
        }
        let mut seg = piece(x, total, u, stair);
        seg.last = next.is_none();
        let u_corner = u_corner.unwrap_or(seg.u_arc);
        let corner_mid = u_corner + Vol((seg.u_end - u_corner).0 / 2);
        (seg, t_end, corner_mid)
    }
}

/// The part of fillet `f` from arc length `a` to `b`.
fn sub_fillet<R: Real>(f: Fillet<R>, a: R, b: R) -> Fillet<R> {
    let (da, db) = (a / f.radius, b / f.radius);
    let sign = if f.sweep >= R::ZERO { R::ONE } else { -R::ONE };
    Fillet {
        start_angle: f.start_angle + sign * da,
        sweep: sign * (db - da),
        ..f
    }
}

fn sat_i32(v: i64) -> i32 {
    v.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::command::section_limits;
    use crate::config::Config;

    fn executor() -> Executor<f64, 4> {
        let cfg: Config = toml::from_str(include_str!("../../configs/seed-paper.toml")).unwrap();
        let mut e = Executor::new(cfg.validate::<f64, 4>().unwrap());
        e.begin([20_000, 20_000, 600], 0).unwrap();
        e
    }

    fn print(dx: i32) -> Command {
        Command::Print {
            dx,
            dy: 0,
            material: 0,
        }
    }

    /// The segments planned, as (command index, start x, length, inverse section).
    fn segs(e: &Executor<f64, 4>) -> Vec<(u32, f64, f64, f64)> {
        e.plan
            .iter()
            .filter_map(|i| match i {
                Item::Seg(s) => Some((s.index, s.start[0], s.len, s.inv_s)),
                _ => None,
            })
            .collect()
    }

    /// A `Section` between two print segments of one bead is taken: the segment before it
    /// keeps the bead's section to its end, the one after it starts the staircase to the
    /// new one, and the bead ends on it. Plan volume is continuous through the stairs.
    #[test]
    fn a_section_mid_bead_holds_from_the_next_segment_over_its_stairs() {
        let mut e = executor();
        let s0 = e.machine.bead_area;
        let s1 = s0 * 1.5;
        let um2 = libm::round(s1 * 1e6) as u32;
        for c in [
            print(5_000),
            Command::Section { um2 },
            print(5_000),
            Command::End,
        ] {
            e.push(c).unwrap();
        }
        let segs = segs(&e);
        // Command 0 at the config's section, whole; command 2 on stairs to the new one.
        assert_eq!(segs[0].0, 0);
        assert_eq!(segs[0].3, 1.0 / s0);
        assert!((segs[0].2 - 5.0).abs() < 1e-9);
        let on_2: Vec<_> = segs.iter().filter(|s| s.0 == 2).collect();
        assert!(on_2.len() > 1, "{segs:?}");
        assert!((on_2.last().unwrap().3 - 1.0e6 / um2 as f64).abs() < 1e-12);
        // Each stair between the two, in order, and the pieces end to end over 5 mm.
        for w in on_2.windows(2) {
            assert!(w[1].3 < w[0].3 && w[1].3 >= 1.0e6 / um2 as f64);
            assert!((w[0].1 + w[0].2 - w[1].1).abs() < 1e-9);
        }
        assert!(on_2[0].3 < 1.0 / s0);
        assert!((on_2[0].1 - 25.0).abs() < 1e-9);
        let total: f64 = on_2.iter().map(|s| s.2).sum();
        assert!((total - 5.0).abs() < 1e-9, "{total}");
        let mut u = Vol::ZERO;
        for i in e.plan.iter() {
            if let Item::Seg(s) = i {
                assert_eq!(s.u_start, u);
                u = s.u_end;
            }
        }
    }

    /// A section outside the machine's range is refused mid-bead as between beads; one
    /// inside it, mid-bead, is not.
    #[test]
    fn a_section_out_of_range_mid_bead_is_refused_by_name() {
        let (lo, hi) = section_limits(executor().machine.bead_area);
        for um2 in [0, lo - 1, hi + 1, u32::MAX] {
            let mut e = executor();
            e.push(print(1_000)).unwrap();
            let r = e.push(Command::Section { um2 });
            let want = Fault::InvalidCommand(CommandError::SectionOutOfRange {
                um2,
                min_um2: lo,
                max_um2: hi,
            });
            assert_eq!(r, Err(super::super::PushError::Rejected(want)), "{um2}");
        }
        for um2 in [lo, hi] {
            let mut e = executor();
            e.push(print(1_000)).unwrap();
            assert_eq!(e.push(Command::Section { um2 }), Ok(()));
            assert_eq!(e.push(print(1_000)), Ok(()));
        }
    }
}

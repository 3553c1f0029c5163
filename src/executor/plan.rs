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
    /// 1 / the bead's section (`Command::Section`), 1/mm^2: only the inverse, so that a
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
                        let (seg, t) = self.finalise(prev, Some((dir, length)));
                        let _ = self.plan.push_back(Item::Seg(seg));
                        if seg.material != material {
                            let mid = seg.u_arc + Vol((seg.u_end - seg.u_arc).0 / 2);
                            let _ = self.boundaries.push_back((mid, material));
                        }
                        self.last_final = Some((seg.material, seg.u_end));
                        self.known_to = Some(seg.u_end);
                        (t, seg.u_end)
                    }
                    None => {
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
                // Between beads only: a section step inside a bead would be a step of the
                // head's speed at constant flow, which the plan does not ramp.
                if self.open.is_some() {
                    return Err(Fault::InvalidCommand(CommandError::SectionInBead));
                }
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
            let (seg, _) = self.finalise(prev, None);
            let _ = self.plan.push_back(Item::Seg(seg));
            let _ = self.ends.push_back(seg.u_end);
            self.last_final = Some((seg.material, seg.u_end));
            self.known_to = Some(seg.u_end);
        }
    }

    /// Fixes an open segment's end: the fillet into `next` (direction, length), or the
    /// bead's end. Returns the segment and the tangent length the next one starts with.
    fn finalise(&self, o: Open<R>, next: Option<(V2<R>, R)>) -> (Seg<R>, R) {
        let s = self.plan_s.0;
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
        let u_arc = o.u_start + Vol::from_mm3(len * s);
        let u_end = u_arc
            + f.map(|f| Vol::from_mm3(f.length() * s))
                .unwrap_or(Vol::ZERO);
        (
            Seg {
                material: o.material,
                start,
                dir: o.dir,
                len,
                fillet: f,
                u_start: o.u_start,
                u_arc,
                u_end,
                last: next.is_none(),
                index: o.index,
                inv_s: self.plan_s.1,
            },
            t_end,
        )
    }
}

fn sat_i32(v: i64) -> i32 {
    v.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

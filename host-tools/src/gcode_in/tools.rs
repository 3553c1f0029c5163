//! The tool-to-inlet map (`--tools 0,1`: tool 0 prints from inlet 0, tool 1 from inlet 1):
//! tool changes and valve commands (`M42 P<n>`, `M106 P<n>`, `SET_PIN PIN=..<n>`, RRF's
//! `G1 .. P<bitmap>`) name a tool (valve) number; the map turns it into an inlet.

use super::error::GcodeInError;

/// Tool (valve) number to inlet.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ToolMap {
    inlets: Vec<u8>,
    machine_inlets: usize,
}

impl ToolMap {
    /// Tool i on inlet i for every inlet of the machine.
    pub fn identity(machine_inlets: usize) -> Self {
        ToolMap {
            inlets: (0..machine_inlets as u8).collect(),
            machine_inlets,
        }
    }

    /// Parses `--tools`: inlet of tool 0, tool 1, ... comma-separated.
    pub fn parse(text: &str, machine_inlets: usize) -> Result<Self, GcodeInError> {
        let bad = |reason: String| GcodeInError::BadToolMap {
            text: text.to_string(),
            reason,
        };
        let mut inlets = Vec::new();
        for (tool, part) in text.split(',').enumerate() {
            let v: u8 = part.trim().parse().map_err(|_| {
                bad(format!(
                    "`{}` (tool {tool}) is not an inlet number",
                    part.trim()
                ))
            })?;
            if v as usize >= machine_inlets {
                return Err(bad(format!(
                    "tool {tool} on inlet {v}, but the machine has {machine_inlets} inlet(s) (0..{})",
                    machine_inlets.saturating_sub(1)
                )));
            }
            inlets.push(v);
        }
        if inlets.len() > 64 {
            return Err(bad("more than 64 tools".into()));
        }
        Ok(ToolMap {
            inlets,
            machine_inlets,
        })
    }

    /// The inlet of `tool` (a `T` number or valve index), on `line` for errors.
    pub fn inlet(&self, tool: u32, line: usize) -> Result<u8, GcodeInError> {
        self.inlets
            .get(tool as usize)
            .copied()
            .ok_or(GcodeInError::NoInlet {
                line,
                tool,
                mapped: self.inlets.len(),
                inlets: self.machine_inlets,
            })
    }
}

/// The valve number at the end of a Klipper pin name (`dollop_valve1` -> 1).
pub fn pin_number(name: &str) -> Option<u32> {
    let digits = name.len() - name.trim_end_matches(|c: char| c.is_ascii_digit()).len();
    if digits == 0 || digits > 3 {
        return None;
    }
    name[name.len() - digits..].parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_and_refusals() {
        let m = ToolMap::parse("1,0", 2).unwrap();
        assert_eq!(m.inlet(0, 1).unwrap(), 1);
        assert_eq!(m.inlet(1, 1).unwrap(), 0);
        assert!(matches!(
            m.inlet(2, 9),
            Err(GcodeInError::NoInlet {
                line: 9,
                tool: 2,
                ..
            })
        ));
        assert!(ToolMap::parse("0,2", 2).is_err());
        assert!(ToolMap::parse("0,x", 2).is_err());
        assert_eq!(pin_number("dollop_valve12"), Some(12));
        assert_eq!(pin_number("fan"), None);
    }
}

//! Test photos from a simulated print: the job run through the executor against a plant
//! that may differ from the config (`Truth`: channel volume, valve dead time, viscosity,
//! supply pressure), the landed paste painted into the design's frame in material colours
//! (bead width from the landed section), then photographed: a random perspective, uneven
//! light, blur and noise. Tests and the README's worked example use it; `dollop inspect` itself does not.

use super::classify::PLATE;
use super::frame::DesignFrame;
use dollop::config::{Config, Pressure};
use dollop::rheology::Rheology;
use dollop::RunState;
use dollop_sim::{Job, RunOptions, RunResult};
use image::{Rgb, RgbImage};
use imageproc::geometric_transformations::{warp_into, Border, Interpolation, Projection};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// How the real machine differs from its config.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Truth {
    /// Real channel length over the configured one.
    pub channel_scale: f64,
    /// Added to every valve's open and close dead time, ms.
    pub dead_time_ms: f64,
    /// Real viscosity (consistency) over the configured one, per inlet.
    pub viscosity_scale: [f64; 4],
    /// Supply pressure the regulator delivers over what the config sets, per inlet (a
    /// gauge or regulator off; valve inlets only).
    pub supply_scale: [f64; 4],
}

impl Default for Truth {
    fn default() -> Self {
        Truth {
            channel_scale: 1.0,
            dead_time_ms: 0.0,
            viscosity_scale: [1.0; 4],
            supply_scale: [1.0; 4],
        }
    }
}

impl Truth {
    /// The real machine's physics: `config` with this truth applied (its pressures as
    /// `config` has them; see [`plant_config`]).
    pub fn physics(&self, config: &Config) -> Config {
        let mut c = config.clone();
        c.channel.channel_length_mm *= self.channel_scale as f32;
        for (i, inlet) in c.inlets.iter_mut().enumerate() {
            inlet.valve_open_delay_ms += self.dead_time_ms as f32;
            inlet.valve_close_delay_ms += self.dead_time_ms as f32;
            let k = self.viscosity_scale.get(i).copied().unwrap_or(1.0) as f32;
            inlet.rheology = match inlet.rheology {
                Rheology::Newtonian { viscosity_pa_s } => Rheology::Newtonian {
                    viscosity_pa_s: viscosity_pa_s * k,
                },
                Rheology::PowerLaw {
                    consistency_pa_sn,
                    flow_index,
                } => Rheology::PowerLaw {
                    consistency_pa_sn: consistency_pa_sn * k,
                    flow_index,
                },
                other => other,
            };
        }
        c
    }
}

/// The plant's config: the real `physics` with the supply pressures that `config`
/// computes (the regulators are set from the config the user has, whatever the truth),
/// each times its `supply_scale` (what the regulator really delivers).
pub fn plant_config(
    config: &Config,
    physics: &Config,
    supply_scale: &[f64; 4],
) -> Result<Config, dollop::ConfigError> {
    let machine = config.validate::<f64, { dollop::config::MAX_CONFIG_INLETS }>()?;
    let mut c = physics.clone();
    for (i, inlet) in c.inlets.iter_mut().enumerate() {
        if inlet.syringe.is_none() {
            let k = supply_scale.get(i).copied().unwrap_or(1.0);
            inlet.pressure_kpa = Pressure::Kpa((machine.inlets[i].supply_pa * k / 1000.0) as f32);
        }
    }
    Ok(c)
}

/// Path length over which a painted bead's width follows its section, mm.
pub const WIDTH_WINDOW_MM: f64 = 0.3;

/// What landed, painted into `frame`: material per pixel or `PLATE`.
pub struct Deposit {
    /// The frame painted.
    pub frame: DesignFrame,
    /// Material per pixel, `PLATE` where nothing landed.
    pub px: Vec<u8>,
}

/// Runs `job` with the executor on `config` and the plant on `plant`, painting what lands.
pub fn deposit(
    config: &Config,
    plant: &Config,
    job: &Job,
    frame: DesignFrame,
) -> Result<(Deposit, RunResult), dollop_sim::SimError> {
    let (w, h) = frame.size();
    let mut px = vec![PLATE; (w * h) as usize];
    let pitch = config.channel.line_pitch_mm as f64;
    let area = pitch * config.channel.layer_height_mm as f64;
    let mut last: Option<[f64; 2]> = None;
    // The bead's width follows its section over the last WIDTH_WINDOW_MM of path: paste
    // flows out sideways over about that length, and a per-cycle ratio of two tiny
    // numbers would paint noise.
    let mut window: std::collections::VecDeque<(f64, f64)> = std::collections::VecDeque::new();
    let (mut sum_ds, mut sum_v) = (0.0f64, 0.0f64);
    // Paste lands under the nozzle and stays: each stretch of path paints the strip across
    // it (not a disk, whose front half would paint paste ahead of the nozzle that has not
    // left it yet); a disk at each bead's start and end makes the round ends.
    let mut painted: Option<[f64; 2]> = None;
    let mut was_landing = false;
    let mut last_m = 0u8;
    let mut last_r = pitch / 2.0;
    let stamp = |px: &mut Vec<u8>, a: [f64; 2], b: [f64; 2], r: f64, m: u8, disk: bool| {
        super::measure::stamp(px, &frame, a, b, r, m, disk)
    };
    let result =
        dollop_sim::run_with_plant::<f32>(config, plant, job, &RunOptions::default(), |c| {
            let p = [c.report.position[0] as f64, c.report.position[1] as f64];
            let ds = last.map_or(0.0, |q| (p[0] - q[0]).hypot(p[1] - q[1]));
            last = Some(p);
            let landing = matches!(c.report.state, RunState::Printing | RunState::Settling)
                && c.landed_volume > 0.0;
            if !landing {
                if was_landing {
                    if let Some(q) = painted {
                        stamp(&mut px, q, q, last_r, last_m, true);
                    }
                }
                was_landing = false;
                painted = None;
                window.clear();
                (sum_ds, sum_v) = (0.0, 0.0);
                return;
            }
            window.push_back((ds, c.landed_volume));
            sum_ds += ds;
            sum_v += c.landed_volume;
            while sum_ds > WIDTH_WINDOW_MM && window.len() > 1 {
                let (d, v) = window.pop_front().unwrap_or((0.0, 0.0));
                sum_ds -= d;
                sum_v -= v;
            }
            let ratio = if sum_ds > 1e-3 {
                (sum_v / (sum_ds * area)).clamp(0.3, 1.6)
            } else {
                1.0
            };
            let r = pitch / 2.0 * ratio;
            if !was_landing {
                stamp(&mut px, p, p, r, c.landing, true);
                painted = Some(p);
            }
            was_landing = true;
            last_m = c.landing;
            last_r = r;
            // A strip whenever the nozzle has moved half a pixel since the last one.
            if let Some(q) = painted {
                if (p[0] - q[0]).hypot(p[1] - q[1]) * frame.px_per_mm >= 0.5 {
                    stamp(&mut px, q, p, r, c.landing, false);
                    painted = Some(p);
                }
            }
        })?;
    Ok((Deposit { frame, px }, result))
}

/// Paste colours for pictures of food: potato, chocolate, tomato, spinach.
pub const FOOD: [[u8; 3]; 4] = [[232, 214, 160], [96, 58, 34], [196, 52, 40], [70, 128, 60]];
/// A plate: blue-grey enamel.
pub const PLATE_COLOUR: [u8; 3] = [150, 165, 185];

/// How the photo is taken.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    /// Photo size, px.
    pub size: (u32, u32),
    /// Share of the photo's width the print spans.
    pub fill: f64,
    /// Largest turn, degrees, and corner jitter (perspective) as a share of the print.
    pub turn_deg: f64,
    /// Perspective: corner jitter as a share of the print's size.
    pub jitter: f64,
    /// Light falloff across the photo (0: even).
    pub falloff: f64,
    /// Blur, px (Gaussian sigma).
    pub blur: f32,
    /// Noise, standard deviation out of 255.
    pub noise: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            size: (1200, 900),
            fill: 0.7,
            turn_deg: 12.0,
            jitter: 0.04,
            falloff: 0.35,
            blur: 1.0,
            noise: 3.0,
            seed: 1,
        }
    }
}

/// Photographs `d` with materials in `colours` on a plate of `plate`. Returns the photo
/// and the footprint's corners in it (top-left, top-right, bottom-right, bottom-left of
/// the design).
pub fn photograph(
    d: &Deposit,
    colours: &[[u8; 3]],
    plate: [u8; 3],
    cam: &Camera,
) -> (RgbImage, [[f64; 2]; 4]) {
    let (fw, fh) = d.frame.size();
    let img = RgbImage::from_fn(fw, fh, |x, y| {
        let m = d.px[(y * fw + x) as usize];
        Rgb(if m == PLATE {
            plate
        } else {
            colours.get(m as usize).copied().unwrap_or([0, 0, 0])
        })
    });
    let mut rng = StdRng::seed_from_u64(cam.seed);
    let (pw, ph) = (cam.size.0 as f64, cam.size.1 as f64);
    let fc = d.frame.corners();
    let (dw, dh) = (fc[1][0] - fc[0][0], fc[3][1] - fc[0][1]);
    let scale = cam.fill * pw / dw.max(dh);
    let th = (rng.random::<f64>() * 2.0 - 1.0) * cam.turn_deg.to_radians();
    let (c, s) = (th.cos(), th.sin());
    let centre = [pw / 2.0, ph / 2.0];
    let mut to = [[0.0; 2]; 4];
    for k in 0..4 {
        let (x, y) = (
            (fc[k][0] - fc[0][0] - dw / 2.0) * scale,
            (fc[k][1] - fc[0][1] - dh / 2.0) * scale,
        );
        let j = cam.jitter * dw.max(dh) * scale;
        to[k] = [
            centre[0] + c * x - s * y + (rng.random::<f64>() * 2.0 - 1.0) * j,
            centre[1] + s * x + c * y + (rng.random::<f64>() * 2.0 - 1.0) * j,
        ];
    }
    let from: [(f32, f32); 4] = std::array::from_fn(|k| (fc[k][0] as f32, fc[k][1] as f32));
    let dst: [(f32, f32); 4] = std::array::from_fn(|k| (to[k][0] as f32, to[k][1] as f32));
    let proj = Projection::from_control_points(from, dst).expect("a non-degenerate quadrilateral");
    let mut photo = RgbImage::new(cam.size.0, cam.size.1);
    warp_into(
        &img,
        proj,
        Interpolation::Bilinear,
        Border::Constant(Rgb(plate)),
        &mut photo,
    );
    let mut photo = imageproc::filter::gaussian_blur_f32(&photo, cam.blur.max(0.01));
    let phi = rng.random::<f64>() * std::f64::consts::TAU;
    for (x, y, p) in photo.enumerate_pixels_mut() {
        let (u, v) = (x as f64 / pw - 0.5, y as f64 / ph - 0.5);
        let light = 1.0 - cam.falloff * (0.5 + u * phi.cos() + v * phi.sin()).clamp(0.0, 1.0);
        for ch in p.0.iter_mut() {
            let n = gauss(&mut rng) * cam.noise;
            *ch = (*ch as f64 * light + n).clamp(0.0, 255.0) as u8;
        }
    }
    (photo, to)
}

fn gauss(rng: &mut StdRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

//! Regenerates the example measurements bundled in `host-tools/data/calibration/`:
//! synthetic data from known parameters plus seeded noise (so the files never change
//! unless this does), for the README's worked example and the bundled-data tests.
//! Run: `cargo run -p dollop-host --example calibration_data`.

use dollop::rheology::{FlowLaw, Rheology};
use dollop_host::calibrate::camera::synth::Synth;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::fmt::Write as _;
use std::path::Path;

/// Standard normal deviate (Box-Muller).
fn gauss(rng: &mut StdRng) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn log_grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (lo.ln() + (hi.ln() - lo.ln()) * i as f64 / (n - 1) as f64).exp())
        .collect()
}

fn write(dir: &Path, name: &str, text: &str) -> std::io::Result<()> {
    std::fs::write(dir.join(name), text)?;
    println!("wrote {}", dir.join(name).display());
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/calibration");
    std::fs::create_dir_all(&dir)?;
    let mut rng = StdRng::seed_from_u64(2024);

    // Pea puree, rotational flow curve: power law K = 12 Pa s^n, n = 0.62, 3 % noise.
    let mut s = String::from(
        "# Synthetic flow curve (calibration_data example): power law K = 12 Pa s^n, n = 0.62, 3 % noise\n\
         shear_rate_1_s,shear_stress_pa\n",
    );
    for g in log_grid(0.5, 200.0, 14) {
        let tau = 12.0 * g.powf(0.62) * (1.0 + 0.03 * gauss(&mut rng));
        let _ = writeln!(s, "{g:.4},{tau:.3}");
    }
    write(&dir, "rheology-puree.csv", &s)?;

    // Hummus, rotational: Herschel-Bulkley tau_y = 35 Pa, K = 12 Pa s^n, n = 0.55, 2 %.
    let mut s = String::from(
        "# Synthetic flow curve: Herschel-Bulkley tau_y = 35 Pa, K = 12 Pa s^n, n = 0.55, 2 % noise\n\
         shear_rate_1_s,shear_stress_pa\n",
    );
    for g in log_grid(0.1, 300.0, 18) {
        let tau = (35.0 + 12.0 * g.powf(0.55)) * (1.0 + 0.02 * gauss(&mut rng));
        let _ = writeln!(s, "{g:.4},{tau:.3}");
    }
    write(&dir, "rheology-hummus.csv", &s)?;

    // Gel, oscillatory sweep: weak gel |G*| = A w^(1/z), A = 450, z = 3.2, 2 %.
    let mut s = String::from(
        "# Synthetic frequency sweep: weak gel A = 450 Pa s^(1/z), z = 3.2, 2 % noise\n\
         angular_frequency_rad_s,complex_modulus_pa\n",
    );
    for w in log_grid(0.1, 100.0, 16) {
        let g = 450.0 * w.powf(1.0 / 3.2) * (1.0 + 0.02 * gauss(&mut rng));
        let _ = writeln!(s, "{w:.4},{g:.2}");
    }
    write(&dir, "rheology-gel-oscillatory.csv", &s)?;

    // Flow through the seed paper's channel (d = 0.8 mm, L = 2.4 mm), two pastes whose
    // effective laws are known, weighed in g/s at density 1.05 g/ml, 2 % noise.
    let mut s = String::from(
        "# Synthetic scale readings through a 0.8 mm x 2.4 mm channel, density 1.05 g/ml, 2 % noise:\n\
         # puree = power law K = 6.0 Pa s^n, n = 0.75; custard = Newtonian 1.6 Pa s\n\
         pressure_kpa,flow_g_s,material\n",
    );
    let v_s = std::f64::consts::PI * 0.8 * 0.8 / 4.0 * 2.4;
    for (name, r) in [
        (
            "puree",
            Rheology::PowerLaw {
                consistency_pa_sn: 6.0,
                flow_index: 0.75,
            },
        ),
        (
            "custard",
            Rheology::Newtonian {
                viscosity_pa_s: 1.6,
            },
        ),
    ] {
        let law: FlowLaw<f64> = FlowLaw::new(&r, 0.8);
        for p_kpa in [1.0, 1.5, 2.2, 3.3, 5.0, 7.5, 11.0] {
            let q = (p_kpa * 1e3 / v_s / law.a).powf(1.0 / law.n);
            let g_s = q * 1.05e-3 * (1.0 + 0.02 * gauss(&mut rng));
            let _ = writeln!(s, "{p_kpa},{g_s:.6},{name}");
        }
    }
    write(&dir, "flow-two-pastes.csv", &s)?;

    // Valve start-up: Weibull M_inf = 0.25 g, n = 1.8, t_lag = 60 ms; 2 mg noise.
    let n = 1.8;
    let k = 10f64.ln() / 0.060f64.powf(n);
    let mut s = format!(
        "# Synthetic valve start-up: Weibull M_inf = 0.25 g, k = {k:.2} s^-n, n = {n}, 2 mg noise\n\
         time_ms,mass_g\n"
    );
    for i in 0..=40 {
        let t = i as f64 * 5.0;
        let m = 0.25 * (1.0 - (-k * (t * 1e-3).powf(n)).exp()) + 0.002 * gauss(&mut rng);
        let _ = writeln!(s, "{t},{m:.4}");
    }
    write(&dir, "lag-valve.csv", &s)?;

    // Syringe start-up: Weibull M_inf = 0.5 g, n = 1.3, t_lag = 0.8 s; 3 mg noise.
    let n = 1.3;
    let k = 10f64.ln() / 0.8f64.powf(n);
    let mut s = format!(
        "# Synthetic syringe start-up: Weibull M_inf = 0.5 g, k = {k:.3} s^-n, n = {n}, 3 mg noise\n\
         time_s,mass_g\n"
    );
    for i in 0..=30 {
        let t = i as f64 * 0.1;
        let m = 0.5 * (1.0 - (-k * t.powf(n)).exp()) + 0.003 * gauss(&mut rng);
        let _ = writeln!(s, "{t:.1},{m:.4}");
    }
    write(&dir, "lag-syringe.csv", &s)?;

    // Camera: 12 frames, 48 px wide filament moving 4.5 px/frame; at 30 fps and
    // 0.02 mm/px that is 0.96 mm and 2.7 mm/s.
    let frames = dir.join("camera");
    Synth::default().write(&frames, 12)?;
    println!("wrote {}/frame_000.png ..", frames.display());
    Ok(())
}

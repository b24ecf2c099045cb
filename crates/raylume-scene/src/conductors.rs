//! Named complex indices of refraction of conductors: the presets Mitsuba 3 knows by name
//! (its `conductor` / `roughconductor` `material` parameter; Tungsten's conductor names are the
//! same), as the RGB `eta` and `k` that Mitsuba's RGB variants use.
//!
//! How the numbers were obtained: Mitsuba 3.9.1 itself (the PyPI wheels `mitsuba==3.9.1` and
//! `drjit==1.5.0` for CPython 3.11, unpacked, not installed or committed), variant
//! `scalar_rgb`, for every `NAME` with a `data/ior/NAME.k.spd` in the wheel:
//! `mi.traverse(mi.load_dict({'type': 'conductor', 'material': NAME}))`, reading `eta.value`
//! and `k.value` (Mitsuba converts the measured spectra to linear sRGB with its
//! `spectrum_list_to_srgb`, clamping out-of-gamut negative channels to 0), printed with 9
//! significant digits, so each value is the `f32` Mitsuba holds. The `_palik` names are
//! Mitsuba's aliases (same data for most). `none` is Mitsuba's default conductor without a
//! material, `eta = 0, k = 1`: a lossless perfect mirror, Fresnel = 1.
//!
//! Names are case-sensitive, as in Mitsuba.

// The 9 significant digits are what identifies each f32 exactly (printed from Mitsuba).
#![allow(clippy::excessive_precision)]

use glam::Vec3;

/// One named conductor: complex index of refraction `eta + i k` per linear-RGB channel,
/// relative to vacuum (air).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConductorIor {
    pub name: &'static str,
    pub eta: [f32; 3],
    pub k: [f32; 3],
}

/// The presets, sorted by name (`none` last).
pub const CONDUCTORS: &[ConductorIor] = &[
    ConductorIor {
        name: "Ag",
        eta: [0.155276194, 0.116727956, 0.138387635],
        k: [4.82835436, 3.12222242, 2.14690113],
    },
    ConductorIor {
        name: "Al",
        eta: [1.65750086, 0.880404711, 0.521244466],
        k: [9.22381115, 6.26950216, 4.83700418],
    },
    ConductorIor {
        name: "AlAs",
        eta: [3.6052959, 3.23293781, 2.21631861],
        k: [0.000679437304, 0.0, 0.00751270913],
    },
    ConductorIor {
        name: "AlAs_palik",
        eta: [3.6052959, 3.23293781, 2.21631861],
        k: [0.000679437304, 0.0, 0.00751270913],
    },
    ConductorIor {
        name: "AlSb",
        eta: [0.0, 4.13937473, 4.6692543],
        k: [0.0, 0.094009079, 1.30057001],
    },
    ConductorIor {
        name: "AlSb_palik",
        eta: [0.0, 4.13937473, 4.6692543],
        k: [0.0, 0.094009079, 1.30057001],
    },
    ConductorIor {
        name: "Au",
        eta: [0.143035978, 0.375307083, 1.44204533],
        k: [3.98299694, 2.38555646, 1.60335922],
    },
    ConductorIor {
        name: "Be",
        eta: [4.18501234, 3.18502927, 2.78406119],
        k: [3.83546591, 3.0101223, 2.868994],
    },
    ConductorIor {
        name: "Be_palik",
        eta: [4.18501234, 3.18502927, 2.78406119],
        k: [3.83546591, 3.0101223, 2.868994],
    },
    ConductorIor {
        name: "Cr",
        eta: [4.36966753, 2.91650534, 1.6549046],
        k: [5.20654678, 4.23130608, 3.75469875],
    },
    ConductorIor {
        name: "CsI",
        eta: [2.14489961, 1.70231891, 1.66242719],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "CsI_palik",
        eta: [2.14489961, 1.70231891, 1.66242719],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "Cu",
        eta: [0.201005474, 0.923749506, 1.10221541],
        k: [3.91326213, 2.45304513, 2.14208984],
    },
    ConductorIor {
        name: "Cu2O",
        eta: [3.55177259, 2.94986963, 2.7518754],
        k: [0.114207022, 0.19389686, 0.606133878],
    },
    ConductorIor {
        name: "Cu2O_palik",
        eta: [3.55177259, 2.94986963, 2.7518754],
        k: [0.114207022, 0.19389686, 0.606133878],
    },
    ConductorIor {
        name: "CuO",
        eta: [3.24754095, 2.44780517, 2.21021962],
        k: [0.521089554, 0.570030749, 0.722178936],
    },
    ConductorIor {
        name: "CuO_palik",
        eta: [3.24754095, 2.44780517, 2.21021962],
        k: [0.521089554, 0.570030749, 0.722178936],
    },
    ConductorIor {
        name: "Cu_palik",
        eta: [0.213228509, 0.919715405, 1.10241079],
        k: [3.92187333, 2.45733166, 2.13658404],
    },
    ConductorIor {
        name: "Hg",
        eta: [2.39893866, 1.44002795, 0.909570396],
        k: [6.32758713, 4.37192488, 3.42176366],
    },
    ConductorIor {
        name: "HgTe",
        eta: [4.77903986, 3.23119617, 2.65990114],
        k: [1.63161266, 1.58081043, 1.72928739],
    },
    ConductorIor {
        name: "HgTe_palik",
        eta: [4.77903986, 3.23119617, 2.65990114],
        k: [1.63161266, 1.58081043, 1.72928739],
    },
    ConductorIor {
        name: "Hg_palik",
        eta: [2.39893866, 1.44002795, 0.909570396],
        k: [6.32758713, 4.37192488, 3.42176366],
    },
    ConductorIor {
        name: "Ir",
        eta: [3.0862999, 2.08219051, 1.61791456],
        k: [5.59215307, 4.06708813, 3.26731205],
    },
    ConductorIor {
        name: "Ir_palik",
        eta: [3.0862999, 2.08219051, 1.61791456],
        k: [5.59215307, 4.06708813, 3.26731205],
    },
    ConductorIor {
        name: "K",
        eta: [0.0640431866, 0.0464097671, 0.0381849147],
        k: [2.10419965, 1.34894001, 0.913125873],
    },
    ConductorIor {
        name: "K_palik",
        eta: [0.0640431866, 0.0464097671, 0.0381849147],
        k: [2.10419965, 1.34894001, 0.913125873],
    },
    ConductorIor {
        name: "Li",
        eta: [0.265790939, 0.195618317, 0.220948622],
        k: [3.54015493, 2.31112337, 1.66860723],
    },
    ConductorIor {
        name: "Li_palik",
        eta: [0.265790939, 0.195618317, 0.220948622],
        k: [3.54015493, 2.31112337, 1.66860723],
    },
    ConductorIor {
        name: "MgO",
        eta: [2.08958387, 1.65072346, 1.59487903],
        k: [4.33269523e-12, 0.0, 2.49864573e-11],
    },
    ConductorIor {
        name: "MgO_palik",
        eta: [2.08958387, 1.65072346, 1.59487903],
        k: [4.33269523e-12, 0.0, 2.49864573e-11],
    },
    ConductorIor {
        name: "Mo",
        eta: [4.48397398, 3.52513075, 2.77631044],
        k: [4.11143732, 3.42082691, 3.15060735],
    },
    ConductorIor {
        name: "Mo_palik",
        eta: [4.48397398, 3.52513075, 2.77631044],
        k: [4.11143732, 3.42082691, 3.15060735],
    },
    ConductorIor {
        name: "Na_palik",
        eta: [0.0602693558, 0.0561409481, 0.061988432],
        k: [3.17927337, 2.11249042, 1.57904112],
    },
    ConductorIor {
        name: "Nb",
        eta: [3.42007399, 2.79009318, 2.39562941],
        k: [3.44139457, 2.73766613, 2.57974577],
    },
    ConductorIor {
        name: "Nb_palik",
        eta: [3.42007399, 2.79009318, 2.39562941],
        k: [3.44139457, 2.73766613, 2.57974577],
    },
    ConductorIor {
        name: "Ni_palik",
        eta: [2.36730456, 1.66337311, 1.46707809],
        k: [4.49881172, 3.05015302, 2.3454392],
    },
    ConductorIor {
        name: "Rh",
        eta: [2.5857935, 1.86021638, 1.55426335],
        k: [6.78226042, 4.70298719, 3.97607303],
    },
    ConductorIor {
        name: "Rh_palik",
        eta: [2.5857935, 1.86021638, 1.55426335],
        k: [6.78226042, 4.70298719, 3.97607303],
    },
    ConductorIor {
        name: "Se",
        eta: [4.05831146, 2.84293509, 2.82085347],
        k: [0.75404954, 0.63844353, 0.521807551],
    },
    ConductorIor {
        name: "Se-e",
        eta: [5.72284889, 4.1657362, 4.08133841],
        k: [0.871136308, 1.10515749, 1.56532025],
    },
    ConductorIor {
        name: "Se-e_palik",
        eta: [5.72284889, 4.1657362, 4.08133841],
        k: [0.871136308, 1.10515749, 1.56532025],
    },
    ConductorIor {
        name: "Se_palik",
        eta: [4.05831146, 2.84293509, 2.82085347],
        k: [0.75404954, 0.63844353, 0.521807551],
    },
    ConductorIor {
        name: "SiC",
        eta: [3.17234159, 2.52597165, 2.47937059],
        k: [7.53766358e-07, 0.0, 1.01925307e-05],
    },
    ConductorIor {
        name: "SiC_palik",
        eta: [3.17234159, 2.52597165, 2.47937059],
        k: [7.53766358e-07, 0.0, 1.01925307e-05],
    },
    ConductorIor {
        name: "SnTe",
        eta: [4.52424955, 1.98164499, 1.2815913],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "SnTe_palik",
        eta: [4.52424955, 1.98164499, 1.2815913],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "Ta",
        eta: [2.06272101, 2.39293885, 2.62792873],
        k: [2.40835977, 1.74148643, 1.9470278],
    },
    ConductorIor {
        name: "Ta_palik",
        eta: [2.06272101, 2.39293885, 2.62792873],
        k: [2.40835977, 1.74148643, 1.9470278],
    },
    ConductorIor {
        name: "Te",
        eta: [7.39023352, 4.48210478, 2.63710594],
        k: [3.25602221, 3.52705884, 3.29205418],
    },
    ConductorIor {
        name: "Te-e",
        eta: [7.50890684, 4.29642868, 2.36998773],
        k: [5.58392859, 4.94720507, 3.99759221],
    },
    ConductorIor {
        name: "Te-e_palik",
        eta: [7.50890684, 4.29642868, 2.36998773],
        k: [5.58392859, 4.94720507, 3.99759221],
    },
    ConductorIor {
        name: "Te_palik",
        eta: [7.39023352, 4.48210478, 2.63710594],
        k: [3.25602221, 3.52705884, 3.29205418],
    },
    ConductorIor {
        name: "ThF4",
        eta: [1.83071363, 1.44222856, 1.38764763],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "ThF4_palik",
        eta: [1.83071363, 1.44222856, 1.38764763],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "TiC",
        eta: [3.70052838, 2.83742213, 2.58228707],
        k: [3.26563501, 2.3515892, 2.17279053],
    },
    ConductorIor {
        name: "TiC_palik",
        eta: [3.70052838, 2.83742213, 2.58228707],
        k: [3.26563501, 2.3515892, 2.17279053],
    },
    ConductorIor {
        name: "TiN",
        eta: [1.64844966, 1.15051603, 1.37982345],
        k: [3.36832809, 1.94349813, 1.10206771],
    },
    ConductorIor {
        name: "TiN_palik",
        eta: [1.64844966, 1.15051603, 1.37982345],
        k: [3.36832809, 1.94349813, 1.10206771],
    },
    ConductorIor {
        name: "TiO2",
        eta: [3.45660996, 2.80173588, 2.90517497],
        k: [0.000105264837, 0.0, 0.00065288652],
    },
    ConductorIor {
        name: "TiO2-e",
        eta: [3.10656452, 2.51316833, 2.58244443],
        k: [2.97516053e-05, 0.0, 0.000182698088],
    },
    ConductorIor {
        name: "TiO2-e_palik",
        eta: [3.10656452, 2.51316833, 2.58244443],
        k: [2.97516053e-05, 0.0, 0.000182698088],
    },
    ConductorIor {
        name: "TiO2_palik",
        eta: [3.45660996, 2.80173588, 2.90517497],
        k: [0.000105264837, 0.0, 0.00065288652],
    },
    ConductorIor {
        name: "VC",
        eta: [3.65756607, 2.75273609, 2.53267193],
        k: [3.06830072, 2.19868731, 1.9631927],
    },
    ConductorIor {
        name: "VC_palik",
        eta: [3.65756607, 2.75273609, 2.53267193],
        k: [3.06830072, 2.19868731, 1.9631927],
    },
    ConductorIor {
        name: "VN",
        eta: [2.86560225, 2.11918902, 1.94009113],
        k: [3.03224254, 2.05611563, 1.6163063],
    },
    ConductorIor {
        name: "VN_palik",
        eta: [2.86560225, 2.11918902, 1.94009113],
        k: [3.03224254, 2.05611563, 1.6163063],
    },
    ConductorIor {
        name: "V_palik",
        eta: [4.27758217, 3.51294875, 2.76107144],
        k: [3.49130082, 2.88945484, 3.11152196],
    },
    ConductorIor {
        name: "W",
        eta: [4.37081671, 3.30024648, 2.99840736],
        k: [3.50064063, 2.6048739, 2.27323318],
    },
    ConductorIor {
        name: "a-C",
        eta: [2.94404578, 2.22713637, 1.9681617],
        k: [0.887464881, 0.799298525, 0.815289974],
    },
    ConductorIor {
        name: "d-C",
        eta: [2.70871973, 2.31882572, 2.22889757],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "d-C_palik",
        eta: [2.70871973, 2.31882572, 2.22889757],
        k: [0.0, 0.0, 0.0],
    },
    ConductorIor {
        name: "none",
        eta: [0.0, 0.0, 0.0],
        k: [1.0, 1.0, 1.0],
    },
];

/// The complex IOR `(eta, k)` of the conductor Mitsuba calls `name` (for example `"Cu"`,
/// `"Au"`, `"Ag"`, `"Al"`, `"Cr"`; `"none"`: Fresnel = 1), or `None` for a name it does not
/// know.
pub fn conductor_ior(name: &str) -> Option<(Vec3, Vec3)> {
    CONDUCTORS
        .iter()
        .find(|c| c.name == name)
        .map(|c| (Vec3::from(c.eta), Vec3::from(c.k)))
}

/// The known names, in [`CONDUCTORS`]' order.
pub fn conductor_names() -> impl Iterator<Item = &'static str> + Clone {
    CONDUCTORS.iter().map(|c| c.name)
}

/// The known names joined with ", ", for error messages.
pub fn conductor_names_list() -> String {
    conductor_names().collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Normal-incidence reflectance `((eta - 1)² + k²) / ((eta + 1)² + k²)`.
    fn f0(eta: f32, k: f32) -> f32 {
        ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k)
    }

    #[test]
    fn names_are_unique_sorted_and_found() {
        let names: Vec<_> = conductor_names().collect();
        assert_eq!(names.len(), 72);
        let mut sorted = names[..names.len() - 1].to_vec();
        sorted.sort_unstable();
        assert_eq!(sorted, names[..names.len() - 1]);
        sorted.dedup();
        assert_eq!(sorted.len(), names.len() - 1);
        for n in &names {
            assert!(conductor_ior(n).is_some(), "{n}");
        }
        for n in ["Cu", "Au", "Ag", "Al", "Cr", "W", "Hg", "Ir", "TiN", "none"] {
            assert!(names.contains(&n), "{n}");
        }
        assert_eq!(conductor_ior("cu"), None);
        assert_eq!(conductor_ior("gold"), None);
        assert!(conductor_names_list().starts_with("Ag, Al, AlAs"));
        assert!(
            CONDUCTORS
                .iter()
                .all(|c| c.eta.iter().chain(&c.k).all(|v| v.is_finite() && *v >= 0.0))
        );
    }

    #[test]
    fn the_common_metals_have_their_known_colours() {
        // Mitsuba 3.9.1's scalar_rgb values, and the colours they make at normal incidence:
        // copper and gold reflect red most and blue least, silver and aluminium are near
        // neutral and bright, chromium grey and darker.
        let (eta, k) = conductor_ior("Cu").unwrap();
        assert_eq!(eta, Vec3::new(0.201005474, 0.923749506, 1.10221541));
        assert_eq!(k, Vec3::new(3.91326213, 2.45304513, 2.14208984));
        let rgb = |name: &str| {
            let (e, k) = conductor_ior(name).unwrap();
            Vec3::new(f0(e.x, k.x), f0(e.y, k.y), f0(e.z, k.z))
        };
        for name in ["Cu", "Au"] {
            let c = rgb(name);
            assert!(c.x > c.y && c.y > c.z && c.x > 0.9, "{name} {c}");
        }
        for (name, spread) in [("Ag", 0.08), ("Al", 0.02)] {
            let c = rgb(name);
            assert!(
                c.min_element() > 0.9 && c.max_element() - c.min_element() < spread,
                "{name} {c}"
            );
        }
        let cr = rgb("Cr");
        assert!(cr.min_element() > 0.5 && cr.max_element() < 0.7, "Cr {cr}");
        assert_eq!(conductor_ior("none"), Some((Vec3::ZERO, Vec3::ONE)));
    }
}

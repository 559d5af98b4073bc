//! A coarse-start setting as the examples `coarse_start` and `fine_depth` take it.

use residual_nerf::render::view::COARSE_SPACING;

/// `off` (every ray from the box: `None`), a margin (at the default first-pass spacing
/// `COARSE_SPACING`), or `MARGIN@MRAD` (`1@0`: two passes at any size): the margin and the
/// spacing in radians.
pub fn parse(s: &str) -> Result<Option<(u32, f32)>, String> {
    if s == "off" {
        return Ok(None);
    }
    let (margin, mrad) = s.split_once('@').unwrap_or((s, ""));
    let margin = margin.parse().map_err(|_| format!("'{s}' is not a margin"))?;
    let spacing = match mrad {
        "" => COARSE_SPACING,
        m => m.parse::<f32>().map_err(|_| format!("'{s}' is not a spacing in mrad"))? * 1e-3,
    };
    Ok(Some((margin, spacing)))
}

/// The name a setting is printed under.
pub fn name(setting: Option<(u32, f32)>) -> String {
    setting.map_or("from the box".into(), |(m, s)| format!("margin {m} spacing {:.1} mrad", s * 1e3))
}

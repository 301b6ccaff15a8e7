use crate::base::LegError;
use crate::control::STIFFNESS_MAX_NM_PER_RAD;
use pma_model::error::within;
use serde::{Deserialize, Serialize};

/// `[control.path]`: path control's tunnel and support.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PathSettings {
    /// Half-width of the tunnel around the path in the hip-knee plane (deg).
    #[serde(default = "default_width")]
    pub width_deg: f64,
    /// Stiffness of the wall beyond it (N m/rad).
    #[serde(default = "default_wall")]
    pub wall_nm_per_rad: f64,
    /// Supportive torque along the path (N m, as a vector in the hip-knee plane).
    #[serde(default)]
    pub support_nm: f64,
}

fn default_width() -> f64 {
    5.0
}

fn default_wall() -> f64 {
    100.0
}

impl Default for PathSettings {
    fn default() -> Self {
        Self {
            width_deg: default_width(),
            wall_nm_per_rad: default_wall(),
            support_nm: 0.0,
        }
    }
}

impl PathSettings {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), LegError> {
        within(
            "control.path.width_deg",
            self.width_deg,
            0.0,
            30.0,
            "must be 0 to 30 deg (a tunnel half-width in the hip-knee plane)",
        )?;
        within(
            "control.path.wall_nm_per_rad",
            self.wall_nm_per_rad,
            0.0,
            STIFFNESS_MAX_NM_PER_RAD,
            "must be 0 to 15000 N m/rad",
        )?;
        within(
            "control.path.support_nm",
            self.support_nm,
            0.0,
            100.0,
            "must be 0 to 100 N m",
        )?;
        Ok(())
    }
}

/// Points of the reference's path over a stride.
const PATH_POINTS: usize = 200;

/// Segments scanned each way from the last nearest one (a stride's 200 segments pass in
/// 1-2 s, a few per 1 ms period).
const LOCAL_SEGMENTS: usize = 12;

/// The reference's path over one stride in the hip-knee plane (rad), closed.
#[derive(Debug, Clone)]
pub struct Tunnel {
    points: Vec<[f64; 2]>,
    width_rad: f64,
}

/// Where a pose is against the tunnel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathPoint {
    /// From the nearest point of the path to the pose (rad).
    pub offset_rad: [f64; 2],
    /// Distance to the path (rad).
    pub distance_rad: f64,
    /// Unit tangent of the path there, in the gait's direction.
    pub tangent: [f64; 2],
}

impl Tunnel {
    /// The path of `gait` over its stride after the start-up, of half-width `width_deg`.
    pub fn new(gait: &crate::gait::GaitReference, width_deg: f64) -> Self {
        let t0 = gait.ramp_s() + gait.stride_period_s();
        let points = (0..PATH_POINTS)
            .map(|i| {
                let g = gait.sample(t0 + gait.stride_period_s() * i as f64 / PATH_POINTS as f64);
                [g.hip.angle_rad, g.knee.angle_rad]
            })
            .collect();
        Self {
            points,
            width_rad: width_deg.to_radians(),
        }
    }

    /// Half-width (rad).
    pub fn width_rad(&self) -> f64 {
        self.width_rad
    }

    /// The nearest point of the path to `q` (a scan of all its segments).
    pub fn locate(&self, q: [f64; 2]) -> PathPoint {
        self.nearest(q, 0..self.points.len()).0
    }

    /// As [`Tunnel::locate`], scanning first only the segments within `LOCAL_SEGMENTS` of
    /// `*hint` (the last one found, updated): a leg moves a few segments per period. A
    /// distance within the tunnel found so is within it for the full scan too (the full
    /// scan can only find a nearer point); beyond it, all segments are scanned, so that
    /// whether the leg is inside, and the wall's push, are exactly the full scan's.
    pub fn locate_near(&self, q: [f64; 2], hint: &mut usize) -> PathPoint {
        let n = self.points.len();
        let start = *hint + n - LOCAL_SEGMENTS;
        let (mut at, mut index) =
            self.nearest(q, (start..start + 2 * LOCAL_SEGMENTS + 1).map(|i| i % n));
        if at.distance_rad > self.width_rad {
            (at, index) = self.nearest(q, 0..n);
        }
        *hint = index;
        at
    }

    /// The nearest point over segments `range` and its segment's index.
    fn nearest(&self, q: [f64; 2], range: impl Iterator<Item = usize>) -> (PathPoint, usize) {
        let n = self.points.len();
        let mut best = PathPoint {
            offset_rad: [f64::INFINITY; 2],
            distance_rad: f64::INFINITY,
            tangent: [1.0, 0.0],
        };
        let mut index = 0;
        // Compared squared: `hypot`, once per segment, was 5 % of a two-leg period.
        let mut best_d2 = f64::INFINITY;
        for i in range {
            let a = self.points[i];
            let b = self.points[(i + 1) % n];
            let ab = [b[0] - a[0], b[1] - a[1]];
            let len2 = ab[0] * ab[0] + ab[1] * ab[1];
            if len2 <= 0.0 {
                continue;
            }
            let s = (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / len2).clamp(0.0, 1.0);
            let offset = [q[0] - a[0] - s * ab[0], q[1] - a[1] - s * ab[1]];
            let d2 = offset[0] * offset[0] + offset[1] * offset[1];
            if d2 < best_d2 {
                best_d2 = d2;
                let len = len2.sqrt();
                best.offset_rad = offset;
                best.tangent = [ab[0] / len, ab[1] / len];
                index = i;
            }
        }
        if best_d2.is_finite() {
            best.distance_rad = best.offset_rad[0].hypot(best.offset_rad[1]);
        }
        (best, index)
    }
}

//! 2×3 affine maps in pixel coordinates (x = column, y = row, pixel centres at integers).
//!
//! A registration is stored as the map from simulated to real pixel coordinates, so that
//! `real(M·p) ≈ sim(p)` — OpenCV's `warpAffine(sim, M, (w, h)) ≈ real`. Angles follow
//! OpenCV's `getRotationMatrix2D`: positive = counter-clockwise as displayed (y axis down).

/// A translation within this many pixels of whole pixels is applied as the whole-pixel
/// shift ([`Affine::snapped`]). Measured, snapping a subpixel part f misaligns by f and
/// biases PSNR more than bicubic resampling does for f ≥ 0.02 px on a clean frame, so only
/// shifts whole to within the registration's own precision are snapped
/// (docs/registration.md).
pub const INTEGER_SNAP: f64 = 0.01;

/// `[[a, b, tx], [c, d, ty]]`: `(x, y) ↦ (a·x + b·y + tx, c·x + d·y + ty)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine(pub [[f64; 3]; 2]);

impl Affine {
    pub const IDENTITY: Affine = Affine([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);

    pub fn translation(dx: f64, dy: f64) -> Affine {
        Affine([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    }

    /// Rotation by `angle_deg` (OpenCV sense) and uniform `scale` about `centre` (x, y):
    /// the matrix `cv2.getRotationMatrix2D(centre, angle_deg, scale)` returns.
    pub fn rotation_scale(angle_deg: f64, scale: f64, centre: (f64, f64)) -> Affine {
        let (sin, cos) = angle_deg.to_radians().sin_cos();
        let (a, b) = (scale * cos, scale * sin);
        let (cx, cy) = centre;
        Affine([[a, b, (1.0 - a) * cx - b * cy], [-b, a, b * cx + (1.0 - a) * cy]])
    }

    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        let m = &self.0;
        (m[0][0] * x + m[0][1] * y + m[0][2], m[1][0] * x + m[1][1] * y + m[1][2])
    }

    /// `self ∘ other`: the map `p ↦ self(other(p))`.
    pub fn compose(&self, other: &Affine) -> Affine {
        let (a, b) = (&self.0, &other.0);
        let mut out = [[0.0; 3]; 2];
        for (i, row) in out.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = a[i][0] * b[0][j] + a[i][1] * b[1][j] + if j == 2 { a[i][2] } else { 0.0 };
            }
        }
        Affine(out)
    }

    /// The inverse map, or `None` when the linear part is singular (or not finite).
    pub fn inverse(&self) -> Option<Affine> {
        let m = &self.0;
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        if !(det.is_finite() && det.abs() > 1e-12) {
            return None;
        }
        let (a, b, c, d) = (m[1][1] / det, -m[0][1] / det, -m[1][0] / det, m[0][0] / det);
        let (tx, ty) = (m[0][2], m[1][2]);
        Some(Affine([[a, b, -(a * tx + b * ty)], [c, d, -(c * tx + d * ty)]]))
    }

    /// Rotation angle in degrees (OpenCV sense) of the nearest similarity.
    pub fn angle_deg(&self) -> f64 {
        let m = &self.0;
        (m[0][1] - m[1][0]).atan2(m[0][0] + m[1][1]).to_degrees()
    }

    /// Uniform scale: `sqrt(|det|)` of the linear part.
    pub fn scale(&self) -> f64 {
        let m = &self.0;
        (m[0][0] * m[1][1] - m[0][1] * m[1][0]).abs().sqrt()
    }

    /// `(dy, dx)`: the translation part, scikit-image's order.
    pub fn shift(&self) -> (f64, f64) {
        (self.0[1][2], self.0[0][2])
    }

    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|v| v.is_finite())
    }

    /// Largest distance between the images of the frame's four corner pixels under
    /// `self` and under `other`, in pixels: how far apart the two maps put the frame.
    pub fn corner_distance(&self, other: &Affine, rows: usize, cols: usize) -> f64 {
        let (xm, ym) = (cols.saturating_sub(1) as f64, rows.saturating_sub(1) as f64);
        [(0.0, 0.0), (xm, 0.0), (0.0, ym), (xm, ym)]
            .iter()
            .map(|&(x, y)| {
                let (a, b) = (self.apply(x, y), other.apply(x, y));
                (a.0 - b.0).hypot(a.1 - b.1)
            })
            .fold(0.0, f64::max)
    }

    /// The same map on a grid `factor` times coarser (pixel centres at `(p + ½)/factor − ½`,
    /// as [`super::image::Plane::halved`] makes for `factor` 2).
    pub fn at_scale(&self, factor: f64) -> Affine {
        let half = 0.5 / factor - 0.5;
        let down = Affine([[1.0 / factor, 0.0, half], [0.0, 1.0 / factor, half]]);
        let up = Affine([[factor, 0.0, -half * factor], [0.0, factor, -half * factor]]);
        down.compose(self).compose(&up)
    }

    /// The map a warp applies: a pure translation within [`INTEGER_SNAP`] px of whole pixels
    /// becomes the whole-pixel shift (the values are then copied, not smoothed by an
    /// interpolation); any other map is returned as it is.
    pub fn snapped(&self) -> Affine {
        let m = &self.0;
        let linear_identity = m[0][0] == 1.0 && m[0][1] == 0.0 && m[1][0] == 0.0 && m[1][1] == 1.0;
        let (tx, ty) = (m[0][2], m[1][2]);
        let whole = |t: f64| (t - t.round()).abs() <= INTEGER_SNAP;
        if linear_identity && whole(tx) && whole(ty) {
            Affine::translation(tx.round(), ty.round())
        } else {
            *self
        }
    }

    /// Largest displacement of a frame corner: [`Affine::corner_distance`] to the identity.
    pub fn max_displacement(&self, rows: usize, cols: usize) -> f64 {
        self.corner_distance(&Affine::IDENTITY, rows, cols)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Affine, b: &Affine, tol: f64) -> bool {
        a.0.iter().flatten().zip(b.0.iter().flatten()).all(|(x, y)| (x - y).abs() <= tol)
    }

    #[test]
    fn rotation_matches_opencv_and_inverts() {
        // cv2.getRotationMatrix2D((79.5, 59.5), 30, 1.1)
        let m = Affine::rotation_scale(30.0, 1.1, (79.5, 59.5));
        let want = Affine([
            [0.952_627_944_162_882_7, 0.55, -28.958_921_560_949_165],
            [-0.55, 0.952_627_944_162_882_7, 46.543_637_322_308_48],
        ]);
        assert!(close(&m, &want, 1e-9), "{m:?}");
        assert!((m.angle_deg() - 30.0).abs() < 1e-12);
        assert!((m.scale() - 1.1).abs() < 1e-12);
        let id = m.compose(&m.inverse().unwrap());
        assert!(close(&id, &Affine::IDENTITY, 1e-12));
        // the centre is fixed
        let (x, y) = m.apply(79.5, 59.5);
        assert!((x - 79.5).abs() < 1e-12 && (y - 59.5).abs() < 1e-12);
    }

    #[test]
    fn compose_order_and_corners() {
        let t = Affine::translation(2.0, -1.0);
        let r = Affine::rotation_scale(90.0, 1.0, (0.0, 0.0));
        // r then t
        let (x, y) = t.compose(&r).apply(1.0, 0.0);
        let (rx, ry) = r.apply(1.0, 0.0);
        assert!((x - (rx + 2.0)).abs() < 1e-12 && (y - (ry - 1.0)).abs() < 1e-12);
        assert!((t.max_displacement(10, 20) - 5f64.sqrt()).abs() < 1e-12);
        assert_eq!(t.shift(), (-1.0, 2.0));
        assert!(Affine([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]]).inverse().is_none());
        // a shift of 2 px is 1 px at half resolution, and back
        let half = t.at_scale(2.0);
        assert!(close(&half, &Affine::translation(1.0, -0.5), 1e-12), "{half:?}");
        assert!(close(&half.at_scale(0.5), &t, 1e-12));
        let r = Affine::rotation_scale(3.0, 1.02, (10.0, 7.0));
        assert!((r.at_scale(2.0).angle_deg() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn only_near_whole_translations_snap() {
        let near = Affine::translation(2.0 + INTEGER_SNAP, -3.0 - 0.5 * INTEGER_SNAP);
        assert_eq!(near.snapped(), Affine::translation(2.0, -3.0));
        let subpixel = Affine::translation(2.0 + 2.0 * INTEGER_SNAP, -3.0);
        assert_eq!(subpixel.snapped(), subpixel);
        let turned = Affine::rotation_scale(0.5, 1.0, (4.0, 4.0));
        assert_eq!(turned.snapped(), turned);
    }
}

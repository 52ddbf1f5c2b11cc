//! The footprint in a residual's row: the expected residual `e` a return has for its beam's
//! geometry, taken out of the residual (`||x - c|| - r - e`), and its gradient in every
//! column, so that the least squares fit the model (the efficient score; NOTES "Issue 46",
//! sessions 37-38: a residual corrected without its gradient biased the drone's time offset).

use super::Table;
use nalgebra::Vector3;

/// A beam's footprint: a Gaussian of 1-sigma half-angles along and across the scan [rad].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Along the scan, across it [rad].
    pub sigma: [f64; 2],
}

impl Footprint {
    /// The Velodynes' beam: 3.0 mrad along the scan by 1.5 mrad across (the manuals' beam
    /// divergence tables: VLP-16, VLS-128 appendix F), the full angle taken as 4 sigma.
    pub const VELODYNE: Footprint = Footprint::of_divergence([3.0e-3, 1.5e-3]);

    /// From the full-angle divergence along and across the scan [rad] (4 sigma).
    pub const fn of_divergence(full: [f64; 2]) -> Self {
        Self {
            sigma: [full[0] / 4.0, full[1] / 4.0],
        }
    }

    /// The bloom of a return whose beam leaves along `u`, the scan along `s` (both unit, in
    /// the site frame), `rho` [m] from the sensor, `dx` the point less the sphere's centre, on
    /// a sphere of radius `r`. The tabulated rule where one serves the footprint's shape
    /// ([`Table::for_ratio`]), else the quadrature.
    pub fn bloom(
        &self,
        dx: &Vector3<f64>,
        u: &Vector3<f64>,
        s: &Vector3<f64>,
        rho: f64,
        r: f64,
    ) -> Bloom {
        let c = u.cross(s);
        let a_u = dx.dot(u);
        // The centre from the beam's axis, in the plane across it.
        let mv = -(dx - u * a_u);
        let m = [mv.dot(s), mv.dot(&c)];
        let sd = [self.sigma[0] * rho, self.sigma[1] * rho];
        let (e, g) = Table::for_ratio(sd[1] / sd[0])
            .and_then(|t| t.expected_with_gradient(m, sd, r))
            .unwrap_or_else(|| super::expected_with_gradient(m, sd, r));
        Bloom {
            e,
            k: s * g[0] + c * g[1],
            g,
            u: *u,
            s: *s,
            c,
            mv,
            a_u,
        }
    }
}

/// One return's expected residual and what moves it.
#[derive(Debug, Clone, Copy)]
pub struct Bloom {
    /// The expected residual [m].
    pub e: f64,
    /// Its gradient by the point (site frame, with the sign of the residual's: the row's
    /// direction is `n + k`).
    pub k: Vector3<f64>,
    g: [f64; 2],
    u: Vector3<f64>,
    s: Vector3<f64>,
    c: Vector3<f64>,
    mv: Vector3<f64>,
    a_u: f64,
}

impl Bloom {
    /// The change of `e` when the beam's axis turns by `du` and the scan's direction by `ds`
    /// (to first order): the boresight and the attitude turn the footprint with the beam.
    pub fn turned(&self, du: &Vector3<f64>, ds: &Vector3<f64>) -> f64 {
        let dc = du.cross(&self.s) + self.u.cross(ds);
        self.g[0] * (self.a_u * du.dot(&self.s) + self.mv.dot(ds))
            + self.g[1] * (self.a_u * du.dot(&self.c) + self.mv.dot(&dc))
    }
}

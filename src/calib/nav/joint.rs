//! The joint least squares' state and its steps: the sums of one evaluation (the globals'
//! normal matrix, each piece's blocks), the chain prior, the damped step with the pieces
//! eliminated by the block-tridiagonal recursion, and Levenberg-Marquardt over it.

use super::rows::{Row, Split};
use super::{Mat6G1, MatG, MatG6, MountPrior, NavModel, Piece, VecG, G};
use crate::align::window::MAX_TARGETS;
use crate::calib::lm::{Clock, Mat6, Vec6, DRIFT, Q};
use crate::calib::nav::P;
use crate::calib::objective::Problem;
use nalgebra::{Cholesky, Vector3};

/// The state of the joint least squares: the global parameters and every piece's error.
pub(super) struct Joint<'a, 'p> {
    pub(super) pb: &'a Problem<'p>,
    pub(super) z: [f64; G],
    pub(super) clock: Clock,
    /// Each sphere's centre prior's information (1 / sigma^2; 0: free; the slots past the
    /// spheres are held).
    pub(super) centre_info: [f64; MAX_TARGETS],
    /// The chain prior: per piece the diagonal information of its own error, and of its link
    /// to the next (negative).
    pub(super) model: NavModel,
    /// The white noise's variance factor the weights are divided by.
    pub(super) factor: f64,
    /// The share of the footprint's spread at incidence ([`Noise::spread_variance`]) the
    /// weights take (1: as the beam's divergence says; 0: none, as a solve starts;
    /// `weights::spread_share`).
    pub(super) spread: f64,
    /// The prior on the mounting.
    pub(super) mount: MountPrior,
    /// The globals the weights are taken at ([`Self::hold`]).
    pub(super) held: [f64; G],
    /// A second worker for each evaluation's rows (`None`: this thread makes them all).
    pub(super) split: Option<Split<'a>>,
}

/// Sums of one evaluation.
pub(super) struct Sums {
    pub(super) a: MatG,
    pub(super) g: VecG,
    pub(super) cost: f64,
    pub(super) n: usize,
    pub(super) raw: f64,
}

impl Sums {
    /// All zero.
    fn zero() -> Self {
        Self {
            a: MatG::zeros(),
            g: VecG::zeros(),
            cost: 0.0,
            n: 0,
            raw: 0.0,
        }
    }

    /// Row `r` into the global sums (the lower triangle) and its piece's `p` (d, b, g).
    fn add(&mut self, p: &mut Piece, r: &Row) {
        let (jq, jc, je, res, w) = (&r.jq, &r.jc, &r.je, r.res, r.w);
        let cj = Q + 3 * r.sphere;
        // Column by column (the matrices are column-major); each sum takes its terms in
        // the rows' order, as `(x y) w`.
        let a = self.a.as_mut_slice();
        for (b, col) in a.chunks_exact_mut(G).take(Q).enumerate() {
            let jb = jq[b];
            for (c, &ja) in col[b..Q].iter_mut().zip(&jq.as_slice()[b..]) {
                *c += ja * jb * w;
            }
            for (c, jck) in col[cj..cj + 3].iter_mut().zip(jc) {
                *c += jck * jb * w;
            }
        }
        for (k, col) in a.chunks_exact_mut(G).skip(cj).take(3).enumerate() {
            for (c, jcl) in col[cj + k..cj + 3].iter_mut().zip(&jc[k..]) {
                *c += jcl * jc[k] * w;
            }
        }
        for (ga, ja) in self.g.as_mut_slice()[..Q].iter_mut().zip(jq.iter()) {
            *ga += ja * res * w;
        }
        for (gc, jck) in self.g.as_mut_slice()[cj..cj + 3].iter_mut().zip(jc) {
            *gc += jck * res * w;
        }
        for (b, col) in p.d.as_mut_slice().chunks_exact_mut(6).enumerate() {
            for (c, ja) in col.iter_mut().zip(je.iter()) {
                *c += ja * je[b] * w;
            }
        }
        for (a, col) in p.b.as_mut_slice().chunks_exact_mut(G).enumerate() {
            for (c, jqq) in col[..Q].iter_mut().zip(jq.iter()) {
                *c += jqq * je[a] * w;
            }
            for (c, jck) in col[cj..cj + 3].iter_mut().zip(jc) {
                *c += jck * je[a] * w;
            }
        }
        for (ga, ja) in p.g.iter_mut().zip(je.iter()) {
            *ga += ja * res * w;
        }
        self.cost += w * res * res;
        self.raw += res * res;
        self.n += 1;
    }
}

impl<'a, 'p> Joint<'a, 'p> {
    /// At the mounting `b0` (the problem's clock), the centres at their survey and every
    /// piece's error zero.
    pub(super) fn start(
        pb: &'a Problem<'p>,
        b0: &[f64; P],
        model: &NavModel,
        centre_sigma: &[f64],
        pieces: &mut [Piece],
        clock: Clock,
    ) -> Self {
        let mut z = [0.0; G];
        z[..P].copy_from_slice(b0);
        z[P] = pb.dt;
        z[DRIFT] = pb.drift;
        let centre_info = core::array::from_fn(|j| match centre_sigma.get(j) {
            Some(&s) if s > 0.0 && s.is_finite() => 1.0 / (s * s),
            _ => 1e12,
        });
        for p in pieces.iter_mut() {
            p.error = [0.0; 6];
            p.held = [0.0; 6];
        }
        for i in 0..pieces.len() {
            (pieces[i].own, pieces[i].link) = chain_of(model, pieces, i);
        }
        Self {
            pb,
            z,
            clock,
            centre_info,
            model: *model,
            factor: 1.0,
            spread: 0.0,
            mount: MountPrior::default(),
            held: z,
            split: None,
        }
    }
}

impl Joint<'_, '_> {
    pub(super) fn b(&self) -> [f64; P] {
        core::array::from_fn(|i| self.z[i])
    }

    /// Take the weights at the state from now on (iteratively reweighted least squares: they
    /// stay put while the steps look for the minimum).
    pub(super) fn hold(&mut self, pieces: &mut [Piece]) {
        self.held = self.z;
        for p in pieces.iter_mut() {
            p.held = p.error;
        }
    }

    /// Sphere `j`'s centre correction.
    pub(super) fn centre(&self, j: usize) -> Vector3<f64> {
        let cj = Q + 3 * j;
        Vector3::new(self.z[cj], self.z[cj + 1], self.z[cj + 2])
    }

    pub(super) fn problem(&self) -> Problem<'_> {
        Problem {
            dt: self.z[P],
            drift: self.z[DRIFT],
            ..*self.pb
        }
    }

    /// The chain prior's diagonal information per axis of piece `i` (`own`) and the link to
    /// piece `i + 1` (`link`, negative), for the axes with a sigma ([`chain_of`], made once by
    /// [`Self::start`]: it depends on the pieces' times alone).
    pub(super) fn chain(&self, pieces: &[Piece], i: usize) -> ([f64; 6], [f64; 6]) {
        (pieces[i].own, pieces[i].link)
    }

    /// Evaluate at the state: the measurement sums into `pieces` (d, b, g) and the global
    /// ones, priors included.
    pub(super) fn evaluate(&mut self, pieces: &mut [Piece]) -> Sums {
        let mut s = Sums::zero();
        for p in pieces.iter_mut() {
            p.d = Mat6::zeros();
            p.b = MatG6::zeros();
            p.g = Vec6::zeros();
        }
        let add = |p: &mut Piece, r: &Row| s.add(p, r);
        match self.split.take() {
            Some(mut split) => {
                self.each_row_split(&mut split, pieces, add);
                self.split = Some(split);
            }
            None => self.each_row(pieces, add),
        }
        // The lower triangle to the full matrix.
        for a in 0..G {
            for b in 0..a {
                s.a[(b, a)] = s.a[(a, b)];
            }
        }
        // Held parameters: their equation is x = x.
        if !self.clock.dt {
            s.a[(P, P)] = 1.0;
        }
        if !self.clock.drift {
            s.a[(DRIFT, DRIFT)] = 1.0;
        }
        // The mounting's prior.
        for i in 0..P {
            let info = self.mount.info[i];
            if info > 0.0 {
                let d = self.z[i] - self.mount.centre[i];
                s.a[(i, i)] += info;
                s.g[i] += info * d;
                s.cost += info * d * d;
            }
        }
        // The centres' priors (held past the spheres).
        for j in 0..MAX_TARGETS {
            let cj = Q + 3 * j;
            for k in 0..3 {
                if j < self.pb.spheres.len() {
                    let info = self.centre_info[j];
                    s.a[(cj + k, cj + k)] += info;
                    s.g[cj + k] += info * self.z[cj + k];
                    s.cost += info * self.z[cj + k] * self.z[cj + k];
                } else {
                    s.a[(cj + k, cj + k)] = 1.0;
                }
            }
        }
        // The chain prior's gradient and cost: e^T L e.
        let m = pieces.len();
        for i in 0..m {
            let (own, link) = self.chain(pieces, i);
            let prev = if i > 0 { pieces[i - 1].link } else { [0.0; 6] };
            for k in 0..6 {
                let mut le = own[k] * pieces[i].error[k];
                if i + 1 < m {
                    le += link[k] * pieces[i + 1].error[k];
                }
                if i > 0 {
                    le += prev[k] * pieces[i - 1].error[k];
                }
                pieces[i].g[k] += le;
                s.cost += pieces[i].error[k] * le;
            }
        }
        s
    }

    /// The step `(dz, de)` of the damped normal equations (damping `lambda` on every
    /// diagonal, Marquardt's scaling): the pieces eliminated by the block-tridiagonal
    /// recursion. `None` when a block is singular.
    pub(super) fn step(&self, s: &Sums, pieces: &mut [Piece], lambda: f64) -> Option<VecG> {
        let m = pieces.len();
        // Only the globals in use and the gradient: `B`'s rows past them are zero, and so are
        // `Y`'s columns.
        let na = self.active();
        let cols = (0..na).chain(core::iter::once(G));
        // Forward: C_i = M_ii - L_(i-1) C_(i-1)^-1 L_(i-1); Y'_i = R_i - L_(i-1) C_(i-1)^-1 Y'_(i-1).
        let mut prev_link = [0.0; 6];
        for i in 0..m {
            let (own, link) = self.chain(pieces, i);
            let mut c = pieces[i].d;
            for k in 0..6 {
                c[(k, k)] += own[k];
                c[(k, k)] *= 1.0 + lambda;
            }
            let mut y = Mat6G1::zeros();
            for a in 0..6 {
                for q in 0..na {
                    y[(a, q)] = pieces[i].b[(q, a)];
                }
                y[(a, G)] = pieces[i].g[a];
            }
            if i > 0 {
                let ch = Cholesky::pack_dirty(pieces[i - 1].chol);
                let l = Mat6::from_diagonal(&Vec6::from(prev_link));
                let inv_l = ch.solve(&l);
                c -= l * inv_l;
                for q in cols.clone() {
                    let mut col: Vec6 = pieces[i - 1].y.column(q).into_owned();
                    ch.solve_mut(&mut col);
                    for k in 0..6 {
                        y[(k, q)] -= prev_link[k] * col[k];
                    }
                }
            }
            pieces[i].chol = Cholesky::new(c)?.unpack_dirty();
            pieces[i].c = c;
            pieces[i].y = y;
            prev_link = link;
        }
        // Backward: Y_i = C_i^-1 (Y'_i - L_i Y_(i+1)).
        for i in (0..m).rev() {
            let (_, link) = self.chain(pieces, i);
            let ch = Cholesky::pack_dirty(pieces[i].chol);
            for q in cols.clone() {
                let mut col: Vec6 = pieces[i].y.column(q).into_owned();
                if i + 1 < m {
                    for k in 0..6 {
                        col[k] -= link[k] * pieces[i + 1].y[(k, q)];
                    }
                }
                ch.solve_mut(&mut col);
                pieces[i].y.set_column(q, &col);
            }
        }
        // The reduced system: (A - B Y_B) dz = -(g - B Y_g).
        let mut h = s.a;
        for k in 0..G {
            h[(k, k)] *= 1.0 + lambda;
        }
        let mut rhs = s.g;
        for p in pieces.iter() {
            less_piece(&mut h, p, na);
            rhs -= p.b * p.y.column(G);
        }
        let dz = Cholesky::new(h)?.solve(&(-rhs));
        // The pieces: de_i = -(Y_g)_i - (Y_B)_i dz.
        for p in pieces.iter_mut() {
            let de = -(p.y.column(G)) - p.y.fixed_view::<6, G>(0, 0) * dz;
            p.sigma = core::array::from_fn(|k| de[k]);
        }
        Some(dz)
    }

    /// Move the state by the step: the globals by `dz`, each piece by its step (in its
    /// `sigma` scratch, where [`Self::step`] leaves it).
    pub(super) fn apply(&mut self, dz: &VecG, pieces: &mut [Piece]) {
        for k in 0..G {
            self.z[k] += dz[k];
        }
        for p in pieces.iter_mut() {
            for k in 0..6 {
                p.error[k] += p.sigma[k];
            }
        }
    }

    /// Keep every piece's sums and error before a trial step: returns the globals to put back
    /// with [`Self::put_back`].
    pub(super) fn keep(&self, pieces: &mut [Piece]) -> [f64; G] {
        for p in pieces.iter_mut() {
            p.before = super::pieces::BeforeTrial {
                d: p.d,
                b: p.b,
                g: p.g,
                error: p.error,
            };
        }
        self.z
    }

    /// Back to the state [`Self::keep`] kept (its sums too: no evaluation needed).
    pub(super) fn put_back(&mut self, z: [f64; G], pieces: &mut [Piece]) {
        self.z = z;
        for p in pieces.iter_mut() {
            let k = &p.before;
            (p.d, p.b, p.g, p.error) = (k.d, k.b, k.g, k.error);
        }
    }

    /// The reduced information matrix of the global parameters (every piece eliminated), at
    /// the last evaluation's sums.
    pub(super) fn reduced(&self, s: &Sums, pieces: &mut [Piece]) -> Option<MatG> {
        self.step(s, pieces, 0.0)?;
        let mut h = s.a;
        let na = self.active();
        for p in pieces.iter() {
            less_piece(&mut h, p, na);
        }
        Some(h)
    }

    /// Each piece's block of the inverse of the chain's matrix M into its `s` (the globals
    /// held): backward from the forward recursion's C_i, left by the last [`Self::reduced`],
    /// `S_i = C_i^-1 + C_i^-1 L_i S_(i+1) L_i C_i^-1` (NaN where a block is singular).
    pub(super) fn chain_blocks(&self, pieces: &mut [Piece]) {
        let mut next: Option<Mat6> = None;
        for i in (0..pieces.len()).rev() {
            let (_, link) = self.chain(pieces, i);
            let p = &mut pieces[i];
            let Some(cinv) = p.c.try_inverse() else {
                p.s = Mat6::from_element(f64::NAN);
                next = None;
                continue;
            };
            p.s = match next {
                Some(sn) => {
                    let a = cinv * Mat6::from_diagonal(&Vec6::from(link));
                    cinv + a * sn * a.transpose()
                }
                None => cinv,
            };
            next = Some(p.s);
        }
    }

    /// The globals in use: the lm's `Q` and three per sphere (past them `B` is zero).
    pub(super) fn active(&self) -> usize {
        Q + 3 * self.pb.spheres.len().min(MAX_TARGETS)
    }
}

/// The chain prior's diagonal information per axis of piece `i` (`own`) and the link to piece
/// `i + 1` (`link`, negative), for the axes with a sigma: the first-order Gauss-Markov
/// process between the pieces' middles.
fn chain_of(model: &NavModel, pieces: &[Piece], i: usize) -> ([f64; 6], [f64; 6]) {
    let sig = model.sigmas();
    let phi = |a: usize, b: usize| model.phi(&pieces[a], &pieces[b]);
    let mut own = [0.0; 6];
    let mut link = [0.0; 6];
    for k in 0..6 {
        let s2 = sig[k] * sig[k];
        if s2 <= 0.0 {
            own[k] = 1e12;
            continue;
        }
        // Own: the first piece's marginal, or the step from the previous one; plus the
        // next piece's step's phi^2 q.
        own[k] = if i == 0 {
            1.0 / s2
        } else {
            let f = phi(i - 1, i);
            1.0 / ((1.0 - f * f).max(1e-9) * s2)
        };
        if i + 1 < pieces.len() {
            let f = phi(i, i + 1);
            let q = 1.0 / ((1.0 - f * f).max(1e-9) * s2);
            own[k] += f * f * q;
            link[k] = -f * q;
        }
    }
    (own, link)
}

/// `h -= B_p (Y_B)_p` over the first `na` rows and columns (the rest of `B_p` is zero: a
/// sphere slot past the survey's), the Schur complement's share of one piece.
fn less_piece(h: &mut MatG, p: &Piece, na: usize) {
    for c in 0..na {
        let y: [f64; 6] = core::array::from_fn(|k| p.y[(k, c)]);
        for r in 0..na {
            let mut acc = 0.0;
            for (k, yk) in y.iter().enumerate() {
                acc += p.b[(r, k)] * yk;
            }
            h[(r, c)] -= acc;
        }
    }
}

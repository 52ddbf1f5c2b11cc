//! The scenery of a scenario: what stands around the spheres and on the vessel, as the TOML a
//! surveyor edits (`[[box]]`, `[[pole]]`, `[[plane]]`, `[[scatter]]`, `[water]`, `[vessel]`,
//! each sphere's `stand`), validated by key, and built into the simulator's objects with a name
//! and a kind for each (the labels of `synth`'s `labels.bin` refer to them by index).

use crate::config::checks::{check, finite, ScenarioError};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use spherecal::sim::{Frame, Object, Rng, Shape, Water};

/// A box: centre, size along / across its heading and height, heading from north.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Name (labels, reports).
    pub name: String,
    /// Centre [m]: site NED (or body x fwd, y stbd, z down for vessel parts).
    pub center_m: [f64; 3],
    /// Length (along the heading), width, height [m].
    pub size_m: [f64; 3],
    /// Heading of its length [deg from north (body: from x)].
    #[serde(default)]
    pub heading_deg: f64,
    /// Diffuse reflectivity 0..1 (default 0.3: concrete, painted steel).
    #[serde(default = "default_rho")]
    pub reflectivity: f64,
    /// Velocity [m/s, site NED] of a moving object (default still).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_ned_mps: Option<[f64; 3]>,
}

/// A cylinder (pole, bollard, leg, rail, mast) between two points.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoleSpec {
    /// Name.
    pub name: String,
    /// One end of the axis [m] (site NED, or body for vessel parts).
    pub base_m: [f64; 3],
    /// The other end [m].
    pub top_m: [f64; 3],
    /// Radius [m].
    pub radius_m: f64,
    /// Diffuse reflectivity 0..1.
    #[serde(default = "default_rho")]
    pub reflectivity: f64,
    /// Velocity [m/s, site NED] (a person walking).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_ned_mps: Option<[f64; 3]>,
}

/// A ball that is not a target: a buoy, a round fender, a float (a decoy for the extraction).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallSpec {
    /// Name.
    pub name: String,
    /// Centre [m, site NED].
    pub center_m: [f64; 3],
    /// Radius [m].
    pub radius_m: f64,
    /// Diffuse reflectivity 0..1.
    #[serde(default = "default_rho")]
    pub reflectivity: f64,
}

/// A flat rectangle without thickness (a sign, a roof, a fence panel).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// Name.
    pub name: String,
    /// A corner [m, site NED].
    pub corner_m: [f64; 3],
    /// First edge from the corner [m].
    pub edge1_m: [f64; 3],
    /// Second edge from the corner [m].
    pub edge2_m: [f64; 3],
    /// Diffuse reflectivity 0..1.
    #[serde(default = "default_rho")]
    pub reflectivity: f64,
}

/// Random clutter on a floor: crates, posts, standing people or bushes.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScatterSpec {
    /// Name.
    pub name: String,
    /// `crate` (0.4-1.2 m boxes), `post` (0.04-0.12 m radius, 0.8-2.5 m), `person` (a
    /// standing body and head) or `bush` (a ball of 30 leaves, 0.5-1.2 m across).
    pub kind: String,
    /// Centre of the region on its floor [m, site NED].
    pub center_m: [f64; 3],
    /// Extent along and across `heading_deg` [m].
    pub size_m: [f64; 2],
    /// Heading of the region's length [deg from north] (default 0: north, east).
    #[serde(default)]
    pub heading_deg: f64,
    /// How many.
    pub count: usize,
    /// Nothing within this horizontal distance of a sphere centre [m] (default 0.8: a surveyor
    /// keeps the spheres clear).
    #[serde(default = "default_clearance")]
    pub clearance_m: f64,
}

/// The water surface.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WaterSpec {
    /// NED down of the surface [m].
    pub down_m: f64,
    /// Beams within this angle of nadir may glint back [deg] (default 0: none).
    #[serde(default)]
    pub specular_deg: f64,
    /// Probability that such a beam glints.
    #[serde(default)]
    pub specular_prob: f64,
}

/// The vessel's own structure, fixed in the INS body frame (x forward, y starboard, z down).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselSpec {
    /// Cabins, consoles, antennas as boxes.
    #[serde(default, rename = "box")]
    pub boxes: Vec<BoxSpec>,
    /// Rails, stanchions, masts as cylinders.
    #[serde(default, rename = "pole")]
    pub poles: Vec<PoleSpec>,
}

impl WaterSpec {
    /// The simulator's water surface.
    pub fn water(&self) -> Water {
        Water {
            down: self.down_m,
            specular: self.specular_deg.to_radians(),
            specular_prob: self.specular_prob,
        }
    }
}

fn default_rho() -> f64 {
    0.3
}

fn default_clearance() -> f64 {
    0.8
}

/// The scenery of a scenario (the TOML's top-level scene keys), borrowed.
#[derive(Debug, Clone, Copy)]
pub struct SceneSpec<'a> {
    /// Boxes.
    pub boxes: &'a [BoxSpec],
    /// Cylinders.
    pub poles: &'a [PoleSpec],
    /// Flat rectangles.
    pub planes: &'a [PlaneSpec],
    /// Balls that are not targets.
    pub balls: &'a [BallSpec],
    /// Random clutter.
    pub scatter: &'a [ScatterSpec],
    /// Water.
    pub water: Option<&'a WaterSpec>,
    /// The vessel.
    pub vessel: Option<&'a VesselSpec>,
}

/// A target sphere's stand: nothing, one pole, or a surveying tripod.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stand {
    /// Floating in the air (the paper's idealised targets).
    None,
    /// One 25 mm pole from the floor to 15 cm below the sphere.
    Pole,
    /// A surveying tripod: three 30 mm legs from the floor to a head under the sphere, and a
    /// spigot into the sphere.
    Tripod,
}

impl Stand {
    /// From the scenario's word.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "none" => Some(Stand::None),
            "pole" => Some(Stand::Pole),
            "tripod" => Some(Stand::Tripod),
            _ => None,
        }
    }
}

/// A built scene: the objects, and each one's name and kind.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// The simulator's objects (targets first, in the scenario's sphere order).
    pub objects: Vec<Object>,
    /// Each object's name.
    pub names: Vec<String>,
    /// Each object's kind: `sphere`, `stand`, `box`, `pole`, `plane`, the scatter kinds,
    /// `vessel`.
    pub kinds: Vec<&'static str>,
}

impl Scene {
    fn push(&mut self, o: Object, name: impl Into<String>, kind: &'static str) {
        self.objects.push(o);
        self.names.push(name.into());
        self.kinds.push(kind);
    }

    /// The stand under a sphere of centre `c` and radius `r` on a floor at NED down `floor`.
    pub fn add_stand(&mut self, id: &str, stand: Stand, c: Vector3<f64>, r: f64, floor: f64) {
        let bottom = c.z + r;
        match stand {
            Stand::None => {}
            Stand::Pole => self.push(
                Object::new(
                    Shape::pole(Vector3::new(c.x, c.y, floor), 0.025, floor - bottom - 0.15),
                    None,
                ),
                format!("{id} pole"),
                "stand",
            ),
            Stand::Tripod => {
                // Spigot (16 mm) into the sphere, head (80 mm) 2-14 cm below it, legs from the
                // head's bottom to feet spread 0.5 x the height, turned by the sphere's
                // position so that no two tripods look alike.
                let head_top = bottom + 0.02;
                let head_bottom = bottom + 0.14;
                let spigot = Shape::Cylinder {
                    a: Vector3::new(c.x, c.y, bottom - 0.03),
                    b: Vector3::new(c.x, c.y, head_top),
                    r: 0.008,
                };
                self.push(
                    Object::new(spigot, None).with_reflectivity(0.4),
                    format!("{id} tripod spigot"),
                    "stand",
                );
                let head = Shape::Cylinder {
                    a: Vector3::new(c.x, c.y, head_top),
                    b: Vector3::new(c.x, c.y, head_bottom),
                    r: 0.04,
                };
                self.push(
                    Object::new(head, None).with_reflectivity(0.2),
                    format!("{id} tripod head"),
                    "stand",
                );
                let h = (floor - head_bottom).max(0.1);
                let spread = 0.5 * h;
                let turn = (c.x * 0.37 + c.y * 0.61).rem_euclid(core::f64::consts::TAU);
                for k in 0..3 {
                    let a = turn + f64::from(k) * core::f64::consts::TAU / 3.0;
                    let foot = Vector3::new(c.x + spread * a.cos(), c.y + spread * a.sin(), floor);
                    let leg = Shape::Cylinder {
                        a: Vector3::new(c.x, c.y, head_bottom),
                        b: foot,
                        r: 0.015,
                    };
                    self.push(
                        Object::new(leg, None).with_reflectivity(0.35),
                        format!("{id} tripod leg {}", k + 1),
                        "stand",
                    );
                }
            }
        }
    }

    /// Add the scenery of `spec`, keeping scattered clutter clear of the sphere centres. The
    /// scatter layout depends only on each scatter's name and place in the list (not on the
    /// scenario's noise seed).
    pub fn add_scenery(&mut self, spec: &SceneSpec<'_>, centres: &[Vector3<f64>]) {
        for b in spec.boxes {
            let mut o = Object::new(box_shape(b), None).with_reflectivity(b.reflectivity);
            o.velocity = Vector3::from(b.velocity_ned_mps.unwrap_or([0.0; 3]));
            self.push(o, b.name.clone(), "box");
        }
        for p in spec.poles {
            let mut o = Object::new(pole_shape(p), None).with_reflectivity(p.reflectivity);
            o.velocity = Vector3::from(p.velocity_ned_mps.unwrap_or([0.0; 3]));
            self.push(o, p.name.clone(), "pole");
        }
        for p in spec.planes {
            let shape = Shape::Rect {
                p: Vector3::from(p.corner_m),
                u: Vector3::from(p.edge1_m),
                v: Vector3::from(p.edge2_m),
            };
            self.push(
                Object::new(shape, None).with_reflectivity(p.reflectivity),
                p.name.clone(),
                "plane",
            );
        }
        for b in spec.balls {
            let shape = Shape::Sphere {
                c: Vector3::from(b.center_m),
                r: b.radius_m,
            };
            self.push(
                Object::new(shape, None).with_reflectivity(b.reflectivity),
                b.name.clone(),
                "ball",
            );
        }
        for (i, s) in spec.scatter.iter().enumerate() {
            let seed = s
                .name
                .bytes()
                .fold(0xcbf2_9ce4_8422_2325u64 ^ i as u64, |h, b| {
                    (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
                });
            self.add_scatter(s, centres, &mut Rng::new(seed));
        }
        if let Some(v) = spec.vessel {
            for b in &v.boxes {
                let mut o = Object::new(box_shape(b), None).with_reflectivity(b.reflectivity);
                o.frame = Frame::Body;
                self.push(o, format!("vessel {}", b.name), "vessel");
            }
            for p in &v.poles {
                let mut o = Object::new(pole_shape(p), None).with_reflectivity(p.reflectivity);
                o.frame = Frame::Body;
                self.push(o, format!("vessel {}", p.name), "vessel");
            }
        }
    }

    fn add_scatter(&mut self, s: &ScatterSpec, centres: &[Vector3<f64>], rng: &mut Rng) {
        let kind: &'static str = match s.kind.as_str() {
            "crate" => "crate",
            "post" => "post",
            "person" => "person",
            _ => "bush",
        };
        let floor = s.center_m[2];
        let mut placed = 0;
        let mut tries = 0;
        while placed < s.count && tries < 100 * s.count.max(1) {
            tries += 1;
            let (along, across) = (
                rng.range(-0.5, 0.5) * s.size_m[0],
                rng.range(-0.5, 0.5) * s.size_m[1],
            );
            let (sh, ch) = s.heading_deg.to_radians().sin_cos();
            let n = s.center_m[0] + along * ch - across * sh;
            let e = s.center_m[1] + along * sh + across * ch;
            // Its footprint radius, to keep the sphere clear.
            let (foot, shapes) = scatter_shapes(kind, n, e, floor, rng);
            if centres
                .iter()
                .any(|c| (c.x - n).hypot(c.y - e) < s.clearance_m + foot)
            {
                continue;
            }
            placed += 1;
            for (k, (shape, rho)) in shapes.iter().enumerate() {
                let name = if shapes.len() > 1 {
                    &format!("{} {placed}.{}", s.name, k + 1)
                } else {
                    &format!("{} {placed}", s.name)
                };
                self.push(
                    Object::new(*shape, None).with_reflectivity(*rho),
                    name,
                    kind,
                );
            }
        }
    }
}

/// The shapes of one scattered object at (n, e) on a floor, and its footprint radius.
fn scatter_shapes(
    kind: &str,
    n: f64,
    e: f64,
    floor: f64,
    rng: &mut Rng,
) -> (f64, heapless::Vec<(Shape, f64), 32>) {
    let mut out = heapless::Vec::new();
    let base = Vector3::new(n, e, floor);
    let foot = match kind {
        "crate" => {
            let size = [
                rng.range(0.4, 1.2),
                rng.range(0.4, 1.2),
                rng.range(0.4, 1.2),
            ];
            let h = rng.range(0.0, core::f64::consts::PI);
            let _ = out.push((Shape::box_on(base, size, h), rng.range(0.15, 0.5)));
            size[0].hypot(size[1]) / 2.0
        }
        "post" => {
            let r = rng.range(0.04, 0.12);
            let _ = out.push((
                Shape::pole(base, r, rng.range(0.8, 2.5)),
                rng.range(0.2, 0.5),
            ));
            r
        }
        "person" => {
            let h = rng.range(1.55, 1.9);
            let _ = out.push((Shape::pole(base, 0.18, h - 0.22), 0.25));
            let head = Vector3::new(n, e, floor - h + 0.11);
            let _ = out.push((Shape::Sphere { c: head, r: 0.11 }, 0.3));
            0.2
        }
        _ => {
            // A bush: 30 leaves (small spheres) in a ball.
            let rad = rng.range(0.25, 0.6);
            let c = Vector3::new(n, e, floor - rad);
            for _ in 0..30 {
                let mut d = Vector3::new(rng.normal(), rng.normal(), rng.normal());
                d /= d.norm().max(1e-9);
                let x = c + d * (rad * rng.uniform().cbrt());
                let _ = out.push((
                    Shape::Sphere {
                        c: x,
                        r: rng.range(0.03, 0.08),
                    },
                    0.25,
                ));
            }
            rad
        }
    };
    (foot, out)
}

fn box_shape(b: &BoxSpec) -> Shape {
    let c = Vector3::from(b.center_m);
    let base = c + Vector3::new(0.0, 0.0, b.size_m[2] / 2.0);
    Shape::box_on(base, b.size_m, b.heading_deg.to_radians())
}

fn pole_shape(p: &PoleSpec) -> Shape {
    Shape::Cylinder {
        a: Vector3::from(p.base_m),
        b: Vector3::from(p.top_m),
        r: p.radius_m,
    }
}

fn check_rho(rho: f64, key: &str) -> Result<(), ScenarioError> {
    check(
        rho > 0.0 && rho <= 1.0,
        key,
        "expected a reflectivity 0 < rho <= 1",
    )
}

fn check_box(b: &BoxSpec, key: &str) -> Result<(), ScenarioError> {
    check(
        finite(&b.center_m) && b.heading_deg.is_finite(),
        &format!("{key}.center_m"),
        "not finite",
    )?;
    check(
        b.size_m
            .iter()
            .all(|x| x.is_finite() && *x > 0.0 && *x < 1000.0),
        &format!("{key}.size_m"),
        "expected sizes 0 < s < 1000 m",
    )?;
    check(
        b.velocity_ned_mps
            .is_none_or(|v| finite(&v) && v.iter().all(|x| x.abs() < 50.0)),
        &format!("{key}.velocity_ned_mps"),
        "expected |v| < 50 m/s",
    )?;
    check_rho(b.reflectivity, &format!("{key}.reflectivity"))
}

fn check_pole(p: &PoleSpec, key: &str) -> Result<(), ScenarioError> {
    check(
        finite(&p.base_m) && finite(&p.top_m),
        &format!("{key}.base_m"),
        "not finite",
    )?;
    check(
        p.base_m != p.top_m,
        &format!("{key}.top_m"),
        "expected an end different from base_m",
    )?;
    check(
        p.radius_m > 0.0 && p.radius_m < 50.0,
        &format!("{key}.radius_m"),
        "expected 0 < r < 50 m",
    )?;
    check(
        p.velocity_ned_mps
            .is_none_or(|v| finite(&v) && v.iter().all(|x| x.abs() < 50.0)),
        &format!("{key}.velocity_ned_mps"),
        "expected |v| < 50 m/s",
    )?;
    check_rho(p.reflectivity, &format!("{key}.reflectivity"))
}

impl SceneSpec<'_> {
    /// Reject impossible values, naming the key.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        for (i, b) in self.boxes.iter().enumerate() {
            check_box(b, &format!("box[{i}]"))?;
        }
        for (i, p) in self.poles.iter().enumerate() {
            check_pole(p, &format!("pole[{i}]"))?;
        }
        for (i, p) in self.planes.iter().enumerate() {
            let key = format!("plane[{i}]");
            check(
                finite(&p.corner_m) && finite(&p.edge1_m) && finite(&p.edge2_m),
                &format!("{key}.corner_m"),
                "not finite",
            )?;
            check(
                Vector3::from(p.edge1_m)
                    .cross(&Vector3::from(p.edge2_m))
                    .norm()
                    > 1e-6,
                &format!("{key}.edge2_m"),
                "expected two edges that span a plane",
            )?;
            check_rho(p.reflectivity, &format!("{key}.reflectivity"))?;
        }
        for (i, b) in self.balls.iter().enumerate() {
            let key = format!("ball[{i}]");
            check(
                finite(&b.center_m),
                &format!("{key}.center_m"),
                "not finite",
            )?;
            check(
                b.radius_m > 0.0 && b.radius_m < 5.0,
                &format!("{key}.radius_m"),
                "expected 0 < r < 5",
            )?;
            check_rho(b.reflectivity, &format!("{key}.reflectivity"))?;
        }
        for (i, s) in self.scatter.iter().enumerate() {
            let key = format!("scatter[{i}]");
            check(
                matches!(s.kind.as_str(), "crate" | "post" | "person" | "bush"),
                &format!("{key}.kind"),
                "expected crate, post, person or bush",
            )?;
            check(
                finite(&s.center_m) && s.heading_deg.is_finite(),
                &format!("{key}.center_m"),
                "not finite",
            )?;
            check(
                s.size_m
                    .iter()
                    .all(|x| x.is_finite() && *x >= 0.0 && *x < 1000.0),
                &format!("{key}.size_m"),
                "expected extents 0..1000 m",
            )?;
            check(
                s.clearance_m.is_finite() && s.clearance_m >= 0.0,
                &format!("{key}.clearance_m"),
                "expected >= 0",
            )?;
        }
        if let Some(w) = self.water {
            check(w.down_m.is_finite(), "water.down_m", "not finite")?;
            check(
                (0.0..=90.0).contains(&w.specular_deg),
                "water.specular_deg",
                "expected 0..=90",
            )?;
            check(
                (0.0..=1.0).contains(&w.specular_prob),
                "water.specular_prob",
                "expected 0..=1",
            )?;
        }
        if let Some(v) = self.vessel {
            for (i, b) in v.boxes.iter().enumerate() {
                check_box(b, &format!("vessel.box[{i}]"))?;
            }
            for (i, p) in v.poles.iter().enumerate() {
                check_pole(p, &format!("vessel.pole[{i}]"))?;
            }
        }
        Ok(())
    }

    /// Objects this scenery adds at most (scattered bushes count 30 each).
    pub fn max_objects(&self) -> usize {
        let scatter: usize = self
            .scatter
            .iter()
            .map(|s| {
                s.count
                    * match s.kind.as_str() {
                        "bush" => 30,
                        "person" => 2,
                        _ => 1,
                    }
            })
            .sum();
        let vessel = self
            .vessel
            .as_ref()
            .map_or(0, |v| v.boxes.len() + v.poles.len());
        self.boxes.len()
            + self.poles.len()
            + self.planes.len()
            + self.balls.len()
            + scatter
            + vessel
    }
}

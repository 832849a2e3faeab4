//! Level of detail for scenes with many cloths: [`ClothLod`] chooses, per cloth, how much of its
//! simulation runs from how far it is from the [`ClothViewer`]s (or how large it looks to them)
//! and whether any of them sees it; [`ClothBudget`] caps what all of them cost a frame. The
//! plugin writes each cloth's level to its [`ClothLodLevel`].
//!
//! ```
//! use bevy::prelude::*;
//! use bevy_cloth::prelude::*;
//!
//! fn spawn(mut commands: Commands) {
//!     // The camera the levels are chosen for.
//!     commands.spawn((Transform::from_xyz(0.0, 2.0, 10.0), ClothViewer::perspective(0.8, 16.0 / 9.0)));
//!     // Full quality within 15 m, half the substeps to 25 m, every other row and column to 40 m,
//!     // frozen on its targets to 80 m, culled beyond (and whenever no viewer sees it).
//!     commands.spawn((
//!         Cloth::grid(GridSpec::new(16, 16, 0.05)),
//!         ClothPins::new([0, 15]),
//!         ClothLod { reduced: 15.0, coarse: 25.0, frozen: 40.0, culled: 80.0, ..default() },
//!     ));
//!     // All cloths together: at most 4 ms of steps a frame.
//!     commands.insert_resource(ClothBudget::new(4.0));
//! }
//! # bevy::ecs::system::assert_is_system(spawn);
//! ```

use bevy::ecs::prelude::*;
use bevy::math::{Affine3A, Vec3};
use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

use crate::error::{ClothError, non_negative};
use crate::sim::contact::bounds;
use crate::skin::Attachment;

/// How much of a cloth's simulation runs, from all of it to none.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Reflect)]
pub enum LodLevel {
    /// Every substep: exactly the cloth without level of detail.
    #[default]
    Full,
    /// Fewer substeps ([`ClothLod::reduced_detail`] of them; in tolerance mode, a tolerance
    /// that much looser).
    Reduced,
    /// Every other row and column of a lattice cloth simulated, and the rest of its particles
    /// (and so its whole render mesh) put between them (see
    /// [`ClothSim::set_coarse`](crate::sim::ClothSim::set_coarse)); a cloth with no coarse level
    /// runs at [`Reduced`](Self::Reduced) instead.
    Coarse,
    /// No simulation: each particle keeps the pose it had when the cloth froze, carried by its
    /// skin (a skinned particle with a target) or by the cloth's transform (the others), so a
    /// character's cloth follows its character. Its mesh is still written.
    Frozen,
    /// Nothing: no simulation, no targets, no mesh update. On coming back it resumes where it
    /// stopped or is put where [`Frozen`](Self::Frozen) would have carried it
    /// ([`ClothLod::on_return`]).
    Culled,
}

impl LodLevel {
    /// The levels, finest first.
    pub const ALL: [LodLevel; 5] = [
        LodLevel::Full,
        LodLevel::Reduced,
        LodLevel::Coarse,
        LodLevel::Frozen,
        LodLevel::Culled,
    ];

    /// The level's name in lower case, as the inspector and `cloth_cli` print it.
    pub fn name(self) -> &'static str {
        match self {
            LodLevel::Full => "full",
            LodLevel::Reduced => "reduced",
            LodLevel::Coarse => "coarse",
            LodLevel::Frozen => "frozen",
            LodLevel::Culled => "culled",
        }
    }

    /// Whether the cloth steps at this level.
    pub fn steps(self) -> bool {
        self <= LodLevel::Coarse
    }
}

/// What [`ClothLod`]'s thresholds measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect, Serialize, Deserialize)]
pub enum LodMetric {
    /// Distance from the nearest viewer to the cloth's bounding sphere, m; a level applies beyond
    /// its threshold.
    #[default]
    Distance,
    /// The bounding sphere's radius over its distance, in units of the half height the largest
    /// viewer sees at that distance (`r / (d · tan(fov_y / 2))`: 1 fills half the view); a level
    /// applies below its threshold.
    ScreenSize,
}

/// Where a culled cloth is when it comes back ([`ClothLod::on_return`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Reflect, Serialize, Deserialize)]
pub enum CulledReturn {
    /// Where [`LodLevel::Frozen`] would have carried the pose it had when it was culled; it runs
    /// frozen for that step, then at its level.
    #[default]
    Reset,
    /// Where it stopped, as if no time had passed (its pins and targets then pull it to where they
    /// are now).
    Resume,
}

/// Chooses a cloth's [`LodLevel`] each step from the [`ClothViewer`]s: by [`metric`](Self::metric)
/// past the `reduced`, `coarse`, `frozen` and `culled` thresholds (give one the value of the next,
/// or `f32::INFINITY` for distance and 0 for screen size to the last ones, to leave its level
/// out), and culled whenever no viewer sees it
/// ([`cull_unseen`](Self::cull_unseen)). With no viewer, every cloth runs at full quality.
/// [`ClothBudget`] may lower the level further. The level is written to [`ClothLodLevel`].
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect, Serialize, Deserialize)]
#[reflect(Component, Debug)]
#[require(ClothLodLevel)]
#[serde(default, deny_unknown_fields)]
pub struct ClothLod {
    /// What the thresholds measure.
    pub metric: LodMetric,
    /// Past this, [`LodLevel::Reduced`].
    pub reduced: f32,
    /// Past this, [`LodLevel::Coarse`].
    pub coarse: f32,
    /// Past this, [`LodLevel::Frozen`].
    pub frozen: f32,
    /// Past this, [`LodLevel::Culled`].
    pub culled: f32,
    /// How far past a threshold the measure must go before the level changes, as a fraction of
    /// the threshold: a cloth leaves a level at `threshold × (1 ± hysteresis)` and comes back at
    /// `threshold × (1 ∓ hysteresis)`, so a cloth near a threshold does not flicker between two
    /// levels. In `0..1`.
    pub hysteresis: f32,
    /// At [`LodLevel::Reduced`], the fraction of the configured substeps a step takes (see
    /// [`ClothSim::set_detail`](crate::sim::ClothSim::set_detail)), in `(0, 1]`.
    pub reduced_detail: f32,
    /// Cull the cloth while no viewer's view cone holds any of its bounding sphere.
    pub cull_unseen: bool,
    /// Where a culled cloth is when it comes back.
    pub on_return: CulledReturn,
    /// Frames over which a cloth that was frozen blends from its carried pose into its
    /// simulation when it steps again (0: at once).
    pub blend_frames: u32,
}

impl Default for ClothLod {
    /// By distance: full quality within 15 m, [`Reduced`](LodLevel::Reduced) (half the
    /// substeps) to 25 m, [`Coarse`](LodLevel::Coarse) to 40 m, [`Frozen`](LodLevel::Frozen) to
    /// 80 m, culled beyond and when unseen; 10% hysteresis; a thawing cloth blends into its
    /// simulation over 10 frames.
    fn default() -> Self {
        Self {
            metric: LodMetric::Distance,
            reduced: 15.0,
            coarse: 25.0,
            frozen: 40.0,
            culled: 80.0,
            hysteresis: 0.1,
            reduced_detail: 0.5,
            cull_unseen: true,
            on_return: CulledReturn::Reset,
            blend_frames: 10,
        }
    }
}

impl ClothLod {
    /// Checks the values: thresholds not negative and in the metric's order (rising for
    /// distance, falling for screen size), hysteresis in `0..1`, detail in `(0, 1]`.
    pub fn validate(&self) -> Result<(), ClothError> {
        for (field, v) in [
            ("lod.reduced", self.reduced),
            ("lod.coarse", self.coarse),
            ("lod.frozen", self.frozen),
            ("lod.culled", self.culled),
        ] {
            if v.is_nan() || v < 0.0 {
                return Err(ClothError::InvalidValue {
                    field,
                    expected: "not negative",
                    value: v as f64,
                });
            }
        }
        let t = [self.reduced, self.coarse, self.frozen, self.culled];
        let ordered = t.windows(2).all(|w| match self.metric {
            LodMetric::Distance => w[0] <= w[1],
            LodMetric::ScreenSize => w[0] >= w[1],
        });
        if !ordered {
            return Err(ClothError::InvalidValue {
                field: "lod thresholds",
                expected: "reduced, coarse, frozen, culled in order (rising distances, falling \
                           sizes)",
                value: self.frozen as f64,
            });
        }
        non_negative("lod.hysteresis", self.hysteresis)?;
        if self.hysteresis >= 1.0 {
            return Err(ClothError::InvalidValue {
                field: "lod.hysteresis",
                expected: "in 0..1",
                value: self.hysteresis as f64,
            });
        }
        if !(self.reduced_detail > 0.0 && self.reduced_detail <= 1.0) {
            return Err(ClothError::InvalidValue {
                field: "lod.reduced_detail",
                expected: "in (0, 1]",
                value: self.reduced_detail as f64,
            });
        }
        Ok(())
    }

    /// The level for `measure` (distance or screen size) for a cloth now at `current`: past a
    /// threshold by the hysteresis to go coarser, back by it to go finer.
    pub fn level_for(&self, measure: f32, current: LodLevel) -> LodLevel {
        let thresholds = [self.reduced, self.coarse, self.frozen, self.culled];
        // How many thresholds `measure` is past, each scaled by `factor`.
        let past = |factor: f32| -> usize {
            thresholds
                .iter()
                .take_while(|&&t| match self.metric {
                    LodMetric::Distance => measure > t * factor,
                    LodMetric::ScreenSize => measure < t * factor,
                })
                .count()
        };
        let (coarser, finer) = match self.metric {
            LodMetric::Distance => (1.0 + self.hysteresis, 1.0 - self.hysteresis),
            LodMetric::ScreenSize => (1.0 - self.hysteresis, 1.0 + self.hysteresis),
        };
        let now = current as usize;
        let up = past(coarser);
        let down = past(finer);
        LodLevel::ALL[if up > now {
            up
        } else if down < now {
            down
        } else {
            now
        }]
    }
}

/// The level a cloth with [`ClothLod`] ran its latest step at, and what the choice saw; written
/// by the plugin.
#[derive(Component, Debug, Clone, Copy, PartialEq, Default, Reflect)]
#[reflect(Component, Debug)]
pub struct ClothLodLevel {
    /// The level.
    pub level: LodLevel,
    /// The level [`ClothLod`] chose before [`ClothBudget`] lowered it.
    pub wanted: LodLevel,
    /// The measure the level was chosen by (distance, m, or screen size); with no viewer, 0 m
    /// (an infinite size): full quality.
    pub measure: f32,
    /// Whether a viewer saw the cloth.
    pub seen: bool,
}

/// A point of view that [`ClothLod`] chooses levels for: put it on the camera. A cloth is seen
/// while its bounding sphere reaches into the viewer's view cone, around its local −Z axis.
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug)]
#[require(bevy::transform::components::Transform)]
pub struct ClothViewer {
    /// Vertical field of view, rad (for [`LodMetric::ScreenSize`]).
    pub fov_y: f32,
    /// Half the angle of the cone that holds the view, rad (π or more: sees everything).
    pub half_angle: f32,
}

impl ClothViewer {
    /// The viewer of a perspective camera of vertical field of view `fov_y` (rad) and aspect
    /// ratio `aspect` (width over height): its cone holds the view's corners.
    pub fn perspective(fov_y: f32, aspect: f32) -> Self {
        let t = (0.5 * fov_y).tan();
        Self {
            fov_y,
            half_angle: (t * (1.0 + aspect * aspect).sqrt()).atan(),
        }
    }
}

impl Default for ClothViewer {
    /// Bevy's default perspective: 45° vertically, 16:9.
    fn default() -> Self {
        Self::perspective(std::f32::consts::FRAC_PI_4, 16.0 / 9.0)
    }
}

/// A budget for what all cloths with [`ClothLod`] cost a frame: the sum of their steps' times
/// ([`ClothState::last_step_time`](crate::ClothState::last_step_time), CPU time across threads),
/// ms. Each step the plugin hands levels out nearest (or largest on screen) first, each cloth the
/// finest its own [`ClothLod`] allows that fits what is left once the cloths after it have
/// their cheapest level; the costs are each cloth's recent step times at its levels, and the
/// plan leaves [`headroom`](Self::headroom) of the budget free for their frame-to-frame noise. A
/// cloth is never culled by the budget, only lowered as far as [`LodLevel::Frozen`].
#[derive(Resource, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Resource, Debug)]
pub struct ClothBudget {
    /// The budget, ms a frame.
    pub ms: f32,
    /// The fraction of the budget the plan leaves free, in `0..1`: a step's time varies from
    /// frame to frame, so a plan that spends the whole budget overruns it in many frames.
    pub headroom: f32,
}

impl ClothBudget {
    /// A budget of `ms` a frame with the default headroom of 10%.
    pub fn new(ms: f32) -> Self {
        Self { ms, headroom: 0.1 }
    }

    /// What the plan may spend, ms: the budget less its headroom (a headroom outside `0..1`
    /// counts as none).
    pub fn plan_ms(&self) -> f32 {
        let keep = if (0.0..1.0).contains(&self.headroom) {
            1.0 - self.headroom
        } else {
            1.0
        };
        self.ms * keep
    }
}

/// Weight of the newest step time in a cloth's running cost estimates.
const COST_SMOOTHING: f32 = 0.1;

/// A cloth's level of detail at run time: its level, its running cost estimates, its bounding
/// sphere and the pose [`LodLevel::Frozen`] carries.
#[derive(Debug, Clone, Default)]
pub(crate) struct LodState {
    pub level: LodLevel,
    /// A culled cloth coming back that is put where its frozen pose would be, this step.
    pub reset: bool,
    /// The cloth freezes this step: its pose is to be captured.
    pub capture: bool,
    /// Running estimates of a step at full detail, at the coarse level and of a frozen step, ms
    /// (0 until measured).
    pub full_ms: f32,
    pub coarse_ms: f32,
    pub frozen_ms: f32,
    /// The share of its particles the cloth's coarse level steps (`Some(None)`: it has none),
    /// once asked.
    pub coarse_share: Option<Option<f32>>,
    /// Bounding sphere of the particles (centre, radius); `None` once they moved.
    pub bound: Option<(Vec3, f32)>,
    /// The pose the cloth froze in, as its carriers see it.
    pub carried: Option<Carried>,
    /// Scratch for a frozen step: the carried positions and their velocities.
    pub scratch: Vec<Vec3>,
    pub velocities: Vec<Vec3>,
    /// A cloth that thawed, drawn from its carried pose into its simulation.
    pub blend: Option<Blend>,
}

/// The blend of a thawing cloth's carried pose into its simulation ([`ClothLod::blend_frames`]).
#[derive(Debug, Clone)]
pub(crate) struct Blend {
    /// The pose it froze in.
    pub carried: Carried,
    /// Frames of the blend, and those drawn.
    pub frames: u32,
    pub drawn: u32,
    /// Where the carried pose is this step.
    pub target: Vec<Vec3>,
    /// What is drawn this step: the blend of the target and the particles.
    pub positions: Vec<Vec3>,
}

impl Blend {
    /// A blend from `carried` over `frames`.
    pub fn from(carried: Carried, frames: u32) -> Self {
        Self {
            carried,
            frames,
            drawn: 0,
            target: Vec::new(),
            positions: Vec::new(),
        }
    }

    /// Blends `particles` with the carried pose for the next frame drawn into `positions`;
    /// `false` once the blend is over (the particles are drawn as they are).
    pub fn next(&mut self, particles: &[Vec3]) -> bool {
        if self.drawn >= self.frames || self.target.len() != particles.len() {
            return false;
        }
        self.drawn += 1;
        let s = self.drawn as f32 / self.frames as f32;
        self.positions.clear();
        self.positions.extend(
            self.target
                .iter()
                .zip(particles)
                .map(|(c, p)| c.lerp(*p, s)),
        );
        true
    }
}

impl LodState {
    /// The level's step cost by the estimates, ms. Until the coarse level was measured, its
    /// share of the particles of a full step; for a cloth with no coarse level, the reduced
    /// level's, which it runs instead.
    pub fn cost(&self, level: LodLevel, reduced_detail: f32) -> f32 {
        match level {
            LodLevel::Full => self.full_ms,
            LodLevel::Reduced => self.full_ms * reduced_detail,
            LodLevel::Coarse => match self.coarse_share {
                Some(None) => self.full_ms * reduced_detail,
                _ if self.coarse_ms > 0.0 => self.coarse_ms,
                Some(Some(share)) => self.full_ms * share,
                None => self.full_ms * reduced_detail,
            },
            LodLevel::Frozen => self.frozen_ms,
            LodLevel::Culled => 0.0,
        }
    }

    /// Takes the time of a step at `level` (and `detail`) into the estimates.
    pub fn measured(&mut self, level: LodLevel, detail: f32, ms: f32) {
        let (estimate, value) = match level {
            LodLevel::Full | LodLevel::Reduced => (&mut self.full_ms, ms / detail),
            LodLevel::Coarse => (&mut self.coarse_ms, ms),
            LodLevel::Frozen => (&mut self.frozen_ms, ms),
            LodLevel::Culled => return,
        };
        *estimate = if *estimate == 0.0 {
            value
        } else {
            *estimate + COST_SMOOTHING * (value - *estimate)
        };
    }

    /// The bounding sphere of `positions`, kept until they move.
    pub fn bound(&mut self, positions: &[Vec3]) -> (Vec3, f32) {
        *self.bound.get_or_insert_with(|| {
            let (lo, hi) = bounds(positions);
            if lo.cmple(hi).all() {
                (0.5 * (lo + hi), 0.5 * lo.distance(hi))
            } else {
                (Vec3::ZERO, 0.0)
            }
        })
    }
}

/// A pose carried by the cloth's skin and transform: each particle's position in the space of
/// its carrier (the blend of its skin joints' matrices, or the cloth's transform).
#[derive(Debug, Clone)]
pub(crate) struct Carried {
    /// Each particle's position in its carrier's space.
    local: Vec<Vec3>,
    /// Each particle's entry in the attachment whose skin carries it; `NO_ENTRY`: the transform.
    entry: Vec<u32>,
}

const NO_ENTRY: u32 = u32::MAX;

impl Carried {
    /// The pose `positions` as the carriers are now.
    pub fn capture(
        positions: &[Vec3],
        attachment: Option<&Attachment>,
        transform: &Affine3A,
    ) -> Self {
        let mut carried = Self::at_rest(positions, attachment);
        let to_local = transform.inverse();
        for (x, &k) in carried.local.iter_mut().zip(&carried.entry) {
            *x = match attachment.filter(|_| k != NO_ENTRY) {
                Some(a) => a.carrier(k as usize).inverse().transform_point3(*x),
                None => to_local.transform_point3(*x),
            };
        }
        carried
    }

    /// The rest shape `rest` (the cloth's own space, and its skin's bind space) as the pose.
    pub fn at_rest(rest: &[Vec3], attachment: Option<&Attachment>) -> Self {
        let mut entry = vec![NO_ENTRY; rest.len()];
        if let Some(a) = attachment.filter(|a| a.is_skinned()) {
            for (k, &(p, _)) in a.weighted.iter().enumerate() {
                if let Some(e) = entry.get_mut(p as usize) {
                    *e = k as u32;
                }
            }
        }
        Self {
            local: rest.to_vec(),
            entry,
        }
    }

    /// Writes the pose as the carriers are now into `out` (one per particle, as captured).
    pub fn carry(&self, attachment: Option<&Attachment>, transform: &Affine3A, out: &mut [Vec3]) {
        for ((x, &p), &k) in out.iter_mut().zip(&self.local).zip(&self.entry) {
            *x = match attachment.filter(|_| k != NO_ENTRY) {
                Some(a) => a.carrier(k as usize).transform_point3(p),
                None => transform.transform_point3(p),
            };
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.local.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use LodLevel::*;

    #[test]
    fn levels_change_past_their_thresholds_by_the_hysteresis() {
        let lod = ClothLod {
            reduced: 10.0,
            coarse: 15.0,
            frozen: 20.0,
            culled: 40.0,
            hysteresis: 0.1,
            ..Default::default()
        };
        // Out: a level is left only 10% past its threshold.
        assert_eq!(lod.level_for(10.5, Full), Full);
        assert_eq!(lod.level_for(11.5, Full), Reduced);
        assert_eq!(lod.level_for(17.0, Full), Coarse);
        assert_eq!(lod.level_for(25.0, Full), Frozen);
        assert_eq!(lod.level_for(100.0, Full), Culled);
        // Back: only 10% inside it.
        assert_eq!(lod.level_for(9.5, Reduced), Reduced);
        assert_eq!(lod.level_for(8.5, Reduced), Full);
        assert_eq!(lod.level_for(37.0, Culled), Culled);
        assert_eq!(lod.level_for(35.0, Culled), Frozen);
        assert_eq!(lod.level_for(1.0, Culled), Full);
        // Between the two edges a level stays as it is.
        for level in [Full, Reduced] {
            assert_eq!(lod.level_for(10.0, level), level);
        }
        // By screen size: smaller is coarser.
        let size = ClothLod {
            metric: LodMetric::ScreenSize,
            reduced: 0.2,
            coarse: 0.1,
            frozen: 0.05,
            culled: 0.01,
            ..lod
        };
        size.validate().unwrap();
        assert_eq!(size.level_for(0.5, Full), Full);
        assert_eq!(size.level_for(0.1, Full), Reduced);
        assert_eq!(size.level_for(0.001, Full), Culled);
        assert_eq!(size.level_for(0.21, Reduced), Reduced);
        assert_eq!(size.level_for(0.23, Reduced), Full);
        // A level left out.
        let no_reduced = ClothLod {
            reduced: 20.0,
            coarse: 20.0,
            ..lod
        };
        assert_eq!(no_reduced.level_for(25.0, Full), Frozen);
    }

    #[test]
    fn bad_levels_of_detail_are_errors() {
        let lod = ClothLod::default();
        lod.validate().unwrap();
        for (bad, field) in [
            (
                ClothLod {
                    reduced: -1.0,
                    ..lod
                },
                "lod.reduced",
            ),
            (
                ClothLod {
                    culled: f32::NAN,
                    ..lod
                },
                "lod.culled",
            ),
            (
                ClothLod {
                    frozen: 100.0,
                    ..lod
                },
                "lod thresholds",
            ),
            (
                ClothLod {
                    metric: LodMetric::ScreenSize,
                    ..lod
                },
                "lod thresholds",
            ),
            (
                ClothLod {
                    hysteresis: 1.0,
                    ..lod
                },
                "lod.hysteresis",
            ),
            (
                ClothLod {
                    reduced_detail: 0.0,
                    ..lod
                },
                "lod.reduced_detail",
            ),
            (
                ClothLod {
                    reduced_detail: 1.5,
                    ..lod
                },
                "lod.reduced_detail",
            ),
        ] {
            let e = bad.validate().unwrap_err();
            assert!(e.to_string().contains(field), "{bad:?}: {e}");
        }
    }

    #[test]
    fn a_budget_plans_for_what_its_headroom_leaves() {
        assert_eq!(ClothBudget::new(10.0).plan_ms(), 9.0);
        for headroom in [0.0, -0.5, 1.0, f32::NAN] {
            assert_eq!(
                ClothBudget { ms: 10.0, headroom }.plan_ms(),
                10.0,
                "{headroom}"
            );
        }
    }

    #[test]
    fn a_perspective_viewer_sees_its_corners() {
        let v = ClothViewer::perspective(std::f32::consts::FRAC_PI_2, 1.0);
        // tan(45°) · √2: the corner of a square view.
        assert!((v.half_angle - 2f32.sqrt().atan()).abs() < 1e-6);
    }

    #[test]
    fn cost_estimates_follow_the_steps_measured() {
        let mut s = LodState::default();
        s.measured(Full, 1.0, 2.0);
        assert_eq!(s.cost(Full, 0.5), 2.0);
        assert_eq!(s.cost(Reduced, 0.5), 1.0);
        // A reduced step at half detail counts as a full step of twice its time.
        s.measured(Reduced, 0.5, 2.0);
        assert!((s.cost(Full, 0.5) - 2.2).abs() < 1e-6);
        // The coarse level costs its share of the particles until it was measured itself, and
        // the reduced level's where the cloth has none.
        s.coarse_share = Some(Some(0.25));
        assert!((s.cost(Coarse, 0.5) - 0.55).abs() < 1e-6);
        s.measured(Coarse, 1.0, 0.3);
        assert_eq!(s.cost(Coarse, 0.5), 0.3);
        s.coarse_share = Some(None);
        assert!((s.cost(Coarse, 0.5) - 1.1).abs() < 1e-6);
        s.measured(Frozen, 1.0, 0.01);
        assert_eq!(s.cost(Frozen, 0.5), 0.01);
        assert_eq!(s.cost(Culled, 0.5), 0.0);
    }
}

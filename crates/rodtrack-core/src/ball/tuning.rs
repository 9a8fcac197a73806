//! The ball tracker's constants: geometric and statistical bounds, none fitted to a simulator
//! or a validation set.

/// Rays cast from a blob's centre to find the silhouette's edge (at most 64).
pub const N_RAYS: usize = 48;
/// A blob's cell count over the ball's expected image area: from a ball a quarter visible
/// (its edge or an occluder cut it) to 1.5 times the disc (colour spill, blur).
pub const AREA_RATIO_MIN: f64 = 0.25;
/// See [`AREA_RATIO_MIN`].
pub const AREA_RATIO_MAX: f64 = 1.5;
/// A blob's extent (x or y) over the ball's expected diameter: a longer blob is not a ball.
pub const EXTENT_RATIO_MAX: f64 = 1.25;
/// Along a smeared ball's faded end, the most a sample's colour position (field 0, ball 1)
/// may rise over the previous one's a quad further out: noise on a fading mixture, not the
/// ball's colour again (a quarter of the way from the field's colour to the ball's).
pub const BLUR_RISE_MAX: f32 = 0.25;
/// The part of a blob's edges ending in a fade (see [`BLUR_RISE_MAX`]), on opposite sides,
/// that makes it a smeared ball, its centre then placed by symmetry: a smear long enough to
/// move a sphere's fit (its ends fading over more than a quad) fades the rays within 45
/// degrees of the path, a quarter of the outline; a ball standing still beside a shadow fades
/// a ray or two.
pub const SMEAR_FADED_FRACTION: f64 = 0.25;
/// Directions over half a turn in which a smeared ball's image is compared with its mirror.
pub const SMEAR_ANGLES: usize = 16;
/// The largest RMS difference of colour positions (field 0, ball 1) between a smeared ball's
/// image and its mirror about its centre: a tenth of the way between the two colours (as
/// [`RESIDUAL_RATIO_MAX`] bounds a sphere's fit to a tenth of its radius). A ball whose path
/// bends within the exposure (a bounce, a stop in the goal) is no mirror of itself; the
/// sphere's fit then takes it.
pub const SMEAR_ASYMMETRY_MAX: f64 = 0.1;
/// Where a ray from a blob's centre starts looking for the ball's edge, in expected image
/// radii, when the ball's colour is there: a sphere's outline lies at least this far from a
/// centre it holds (an oval image off the optical axis is at most a few percent narrower
/// than its expected radius, and a blob's centre is off by a fraction of a radius for a ball
/// partly hidden). Nearer samples would only be inside. Else the ray starts at 0.3 radii.
pub const RAY_START_RATIO: f64 = 0.6;
/// Edge points a fit needs.
pub const MIN_EDGE_POINTS: usize = 8;
/// Edge points a fit needs when the tracker predicts the ball there: the prediction's two
/// coordinates stand in for two rays, and the fitted centre must then lie within the ball's
/// image radius of the prediction (a ball against a wall or the goal's mouth shows the field
/// only along part of its outline).
pub const MIN_EDGE_POINTS_NEAR_PREDICTION: usize = MIN_EDGE_POINTS - 2;
/// Octants of the silhouette the used edge points must cover (3 of 8: at least a quarter
/// of the outline, which a known radius turns into a centre).
pub const MIN_OCTANTS: usize = 3;
/// Largest RMS distance of the edge rays from the fitted sphere, in ball radii: a worse fit
/// is not a sphere of the ball's size.
pub const RESIDUAL_RATIO_MAX: f64 = 0.1;
/// Half size of the tracking window, in the ball's expected image radii.
pub const WINDOW_RADII: f64 = 3.0;
/// Half size of the window searched first, in the ball's expected image radii: the ball
/// whole with half a radius of the prediction's error to spare (a ball rolling at 2 m/s moves
/// 10 mm in a frame at 200 fps, and the filter predicts it to about a millimetre); only when
/// that finds no ball is the [`WINDOW_RADII`] window searched.
pub const NEAR_WINDOW_RADII: f64 = 1.5;
/// How long the filter predicts a ball it does not see before reporting it lost, s.
pub const PREDICT_S: f64 = 0.1;
/// White acceleration of the constant-velocity filter, mm/s^2 (about 1 g: rolling, spin and
/// small deflections; a kick or a bounce beyond it resets the velocity).
pub const ACCEL_MM_S2: f64 = 10_000.0;
/// Innovation gate, standard deviations: beyond it the ball was kicked or bounced.
pub const GATE_SIGMAS: f64 = 4.0;
/// Floor of the measurement's standard deviation, mm.
pub const MEAS_SIGMA_MIN_MM: f64 = 0.1;
/// The fastest ball the tracker expects, mm/s (the hardest shots, 15 m/s): the
/// velocity's prior standard deviation at first sight, before a second detection gives it, and
/// how far a ball the window misses can have gone since it was last seen (the coarse scan's
/// reach; a faster ball is found when the reach or a band of the field holds it).
pub const MAX_SPEED_MM_S: f64 = 15_000.0;
/// Bands the coarse scan of the whole field is cut into while the filter predicts a ball it
/// has not seen for more than a frame (under a figure, a hand): one band per frame, the whole
/// field every this many frames (20 ms at 200 fps, within [`PREDICT_S`]), so that a hidden
/// ball costs a frame a fraction of a full re-detection. The first frame the window misses
/// the ball scans the part of the field the ball can have reached since it was last seen (at
/// [`MAX_SPEED_MM_S`]), and later frames do too while that is smaller than a band; every frame
/// once the ball is lost for longer than the prediction scans the whole field.
pub const PREDICTED_SCAN_BANDS: usize = 4;

//! The furnace at every scale: a Lambertian surface of albedo ρ under a uniform sky L must
//! render exactly ρ·L on every pixel it covers, however far the camera and however large the
//! object. A self-intersection (a bounce that restarts below its surface and hits it again)
//! multiplies another ρ in, so a single one shows.

mod common;
use common::*;

fn furnace(toml: &str, w: u32, h: u32, expected: f32) {
    let img = render(toml, w, h, 16, 8);
    let bad = img
        .pixels
        .iter()
        .filter(|p| rel_err(**p, [expected; 3]) > 4.0 * f32::EPSILON as f64)
        .count();
    let worst = img
        .pixels
        .iter()
        .map(|p| rel_err(*p, [expected; 3]))
        .fold(0.0, f64::max);
    assert_eq!(
        bad,
        0,
        "{bad} of {} pixels are not {expected} (worst relative error {worst:e})",
        img.pixels.len()
    );
}

#[test]
fn plane_seen_from_ten_thousand_units_with_a_narrow_view() {
    // Every camera ray hits the plane; every cosine bounce must reach the sky.
    for deg in [30.0f64, 60.0, 85.0] {
        let th = deg.to_radians();
        let toml = format!(
            "[camera]\nlook_from = [0, {}, {}]\nlook_at = [3, 0, 2]\nvfov = 0.01\n\
             [sky]\nuniform = [1, 1, 1]\n\
             [[quad]]\nq = [-1000, 0, 1000]\nu = [2000, 0, 0]\nv = [0, 0, -2000]\ncolor = [0.5, 0.5, 0.5]\n",
            1e4 * th.cos(),
            2.0 + 1e4 * th.sin()
        );
        furnace(&toml, 32, 32, 0.5);
    }
}

#[test]
fn sphere_of_radius_1e5_seen_from_1e4_units() {
    // MODEL.md's extreme case: radius 1e5, its surface 1e4 units from the camera.
    let toml = "[camera]\nlook_from = [0, 1e4, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\nvfov = 10\n\
                [sky]\nuniform = [1, 1, 1]\n\
                [[sphere]]\ncenter = [0, -1e5, 0]\nradius = 1e5\ncolor = [0.5, 0.5, 0.5]\n";
    furnace(toml, 32, 32, 0.5);
}

#[test]
fn box_seen_from_ten_thousand_units() {
    let toml = "[camera]\nlook_from = [5e3, 6e3, 7e3]\nlook_at = [0, 0, 0]\nvfov = 0.005\n\
                [sky]\nuniform = [1, 1, 1]\n\
                [[box]]\ncenter = [0, 0, 0]\nhalf_extents = [1, 1, 1]\nrotation = [10, 20, 30]\ncolor = [0.5, 0.5, 0.5]\n";
    furnace(toml, 32, 32, 0.5);
}

#[test]
fn small_sphere_seen_from_ten_thousand_units() {
    let toml = "[camera]\nlook_from = [1e4, 3e3, 2e3]\nlook_at = [0, 0, 0]\nvfov = 0.004\n\
                [sky]\nuniform = [1, 1, 1]\n\
                [[sphere]]\ncenter = [0, 0, 0]\nradius = 1\ncolor = [0.5, 0.5, 0.5]\n";
    furnace(toml, 32, 32, 0.5);
}

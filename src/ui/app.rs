//! The preview's state and what each key does to it. Pure: no terminal, no GPU, so every
//! key → parameter → reset rule is unit-tested here.

use super::keys::{Action, Param};
use crate::output::LinearImage;
use crate::output::cells::CellMode;
use crate::scene::{Material, Scene, Shape};
use glam::{DMat3, DVec3};
use std::time::{Duration, Instant};

/// What the screen shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Preview,
    Help,
}

/// What the main loop must do after an action.
#[derive(Clone, Debug, PartialEq)]
pub enum Effect {
    None,
    /// The scene changed: send it to the renderer, which restarts the accumulation.
    SceneChanged,
    /// Restart the accumulation of the same scene.
    Reset,
    /// The cell mode changed: the preview resolution changes with it.
    Relayout,
    SavePng,
    WriteScene,
    /// The denoiser's mode changed: tell the renderer (the accumulation goes on).
    Denoise(crate::denoise::Mode),
    Quit,
}

/// The latest figures from the renderer.
#[derive(Clone, Debug, Default)]
pub struct Stats {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub samples_per_second: f64,
    pub elapsed: Duration,
    /// Estimated relative RMSE of the image, when known.
    pub noise: Option<f64>,
    /// Estimated relative RMSE of the denoised image shown, when it is denoised.
    pub denoised: Option<crate::common::resolved::Estimate>,
    /// Why `noise` is rough, if it is: shown instead of a confident figure.
    pub doubt: Option<crate::common::resolved::Doubt>,
    pub invalid: u64,
    /// Of `spp`, the samples per pixel the preview's other devices traced (`--adapter 0,1`).
    pub helped: u32,
    /// The accumulation stopped where `noise` reached `--target-error`.
    pub reached: bool,
}

/// Progress of the background PNG save.
#[derive(Clone, Debug, PartialEq)]
pub struct Saving {
    pub path: String,
    pub done: u32,
    pub total: u32,
}

pub struct App {
    /// The scene as edited.
    pub scene: Scene,
    /// The scene as loaded, for `R`.
    pub original: Scene,
    pub selected: usize,
    pub param: Param,
    pub mode: Mode,
    pub cells: CellMode,
    /// Next-event estimation (light sampling) in the preview.
    pub nee: bool,
    /// When the preview is denoised (`d` switches between off and the mode it started
    /// in, or `auto`).
    pub denoise: crate::denoise::Mode,
    /// The mode `d` turns back on.
    pub denoise_on: crate::denoise::Mode,
    /// The adapter, as the status line names it.
    pub adapter: String,
    /// How the image reaches the terminal (`sixel`, `kitty via tmux`, `cells`), in the
    /// status line after the adapter.
    pub graphics: String,
    pub stats: Stats,
    /// The latest preview image.
    pub image: Option<LinearImage>,
    /// A message for the status line, and when it was set.
    pub message: Option<(String, Instant)>,
    pub saving: Option<Saving>,
    /// The link to the terminal as the frames' acknowledgements measure it (`flow`).
    pub link: Option<String>,
    /// Per image pixel, the standard error of its value (for the cells' noise thresholds).
    pub image_sigma: Vec<f32>,
}

/// How long a status message stays.
pub const MESSAGE_TIME: Duration = Duration::from_secs(6);

impl App {
    pub fn new(scene: Scene, adapter: String, cells: CellMode) -> App {
        App {
            original: scene.clone(),
            scene,
            selected: 0,
            param: Param::named("smoothness"),
            mode: Mode::Preview,
            cells,
            nee: true,
            denoise: crate::denoise::Mode::Off,
            denoise_on: crate::denoise::Mode::Auto,
            adapter,
            graphics: "cells".into(),
            stats: Stats::default(),
            image: None,
            message: None,
            saving: None,
            link: None,
            image_sigma: Vec::new(),
        }
    }

    pub fn say(&mut self, msg: impl Into<String>) {
        self.message = Some((msg.into(), Instant::now()));
    }

    /// The message, while it is fresh.
    pub fn current_message(&self) -> Option<&str> {
        self.message
            .as_ref()
            .filter(|(_, t)| t.elapsed() < MESSAGE_TIME)
            .map(|(m, _)| m.as_str())
    }

    /// Label of the selected object (`tomato`, `sphere #3`).
    pub fn selected_label(&self) -> String {
        self.scene
            .labels()
            .get(self.selected)
            .cloned()
            .unwrap_or_else(|| "no objects".into())
    }

    pub fn selected_material(&self) -> Option<&Material> {
        self.scene.objects.get(self.selected).map(|o| &o.material)
    }

    /// The parameter `+ - ] [` adjust: the chosen one, or the one on its key for the
    /// selected material's model (`1` is smoothness, or a pbr material's metallic).
    pub fn active_param(&self) -> Param {
        self.param
            .for_model(self.selected_material().map(|m| m.model))
    }

    /// The current value of a parameter, for display.
    pub fn value(&self, p: Param) -> Option<f64> {
        p.value(&self.scene, self.selected_material())
    }

    /// Applies a key's action.
    pub fn apply(&mut self, action: Action) -> Effect {
        if self.mode == Mode::Help {
            // In the help, ? and Esc close it; q still quits; everything else is ignored.
            return match action {
                Action::ToggleHelp | Action::Back => {
                    self.mode = Mode::Preview;
                    Effect::None
                }
                Action::Quit => Effect::Quit,
                _ => Effect::None,
            };
        }
        let n = self.scene.objects.len();
        match action {
            Action::SelectNext if n > 0 => {
                self.selected = (self.selected + 1) % n;
                Effect::None
            }
            Action::SelectPrev if n > 0 => {
                self.selected = (self.selected + n - 1) % n;
                Effect::None
            }
            Action::SelectNext | Action::SelectPrev => Effect::None,
            Action::Choose(p) => {
                self.param = p;
                Effect::None
            }
            Action::NextParam => {
                // The next one the selected object has (a material's model decides).
                let model = self.selected_material().map(|m| m.model);
                let mut p = self.active_param().next();
                while !p.applies_to(model) {
                    p = p.next();
                }
                self.param = p;
                Effect::None
            }
            Action::Adjust { up, coarse } => self.adjust(up, coarse),
            Action::Orbit { yaw, pitch } => {
                self.orbit(yaw, pitch);
                Effect::SceneChanged
            }
            Action::Move(f, r, u) => {
                self.move_camera(f, r, u);
                Effect::SceneChanged
            }
            Action::Zoom(k) => {
                let fov = Param::named("fov").spec();
                let cam = &mut self.scene.camera;
                cam.vfov = fov.range.clamp(cam.vfov * k, fov.fine);
                Effect::SceneChanged
            }
            Action::RotateSky(deg) => match &mut self.scene.environment {
                Some(e) => {
                    e.rotation = (e.rotation + deg).rem_euclid(360.0);
                    let r = e.rotation;
                    self.say(format!("environment map turned to {r}°"));
                    Effect::SceneChanged
                }
                None => self.no_map(),
            },
            Action::ScaleSky(k) => match &mut self.scene.environment {
                Some(e) => {
                    e.intensity = (e.intensity * k).clamp(1e-6, 1e6);
                    let i = e.intensity;
                    self.say(format!("environment map intensity {i:.3}"));
                    Effect::SceneChanged
                }
                None => self.no_map(),
            },
            Action::FocusOnSelected => self.focus_on_selected(),
            Action::ResetAccumulation => Effect::Reset,
            Action::Revert => {
                self.scene = self.original.clone();
                self.selected = self
                    .selected
                    .min(self.scene.objects.len().saturating_sub(1));
                self.say("reverted every edit");
                Effect::SceneChanged
            }
            Action::SavePng => Effect::SavePng,
            Action::WriteScene => Effect::WriteScene,
            Action::CycleCells => {
                self.cells = self.cells.next();
                Effect::Relayout
            }
            Action::ToggleNee => {
                self.nee = !self.nee;
                self.say(if self.nee {
                    "light sampling on"
                } else {
                    "light sampling off (brute force)"
                });
                Effect::SceneChanged
            }
            Action::ToggleDenoise => {
                use crate::denoise::Mode;
                if self.denoise == Mode::Off {
                    self.denoise = self.denoise_on;
                    self.say(format!("denoiser on ({})", self.denoise.name()));
                } else {
                    self.denoise_on = self.denoise;
                    self.denoise = Mode::Off;
                    self.say("denoiser off: the raw image");
                }
                Effect::Denoise(self.denoise)
            }
            Action::ToggleHelp => {
                self.mode = Mode::Help;
                Effect::None
            }
            Action::Quit | Action::Back => Effect::Quit,
        }
    }

    /// The environment map keys in a scene without one.
    fn no_map(&mut self) -> Effect {
        self.say("no environment map: open the scene with --sky FILE.hdr, or give [sky] a map");
        Effect::None
    }

    fn adjust(&mut self, up: bool, coarse: bool) -> Effect {
        let p = self.active_param();
        if !p.is_material() {
            p.adjust_scene(&mut self.scene, up, coarse);
            return Effect::SceneChanged;
        }
        let Some(obj) = self.scene.objects.get_mut(self.selected) else {
            return Effect::None;
        };
        if !p.adjust_material(&mut obj.material, up, coarse) {
            return Effect::None;
        }
        // A glTF material is edited as one: every object of the same file that uses it
        // changes with the selected one (and `w` writes it as one override).
        let (m, from, key) = (obj.material.clone(), obj.gltf, obj.material_name.clone());
        if from.is_some() {
            for o in &mut self.scene.objects {
                if o.gltf == from && o.material_name == key {
                    o.material = m.clone();
                }
            }
        }
        Effect::SceneChanged
    }

    fn orbit(&mut self, yaw: f64, pitch: f64) {
        let cam = &mut self.scene.camera;
        let up = cam.up.normalize();
        let mut offset = cam.look_from - cam.look_at;
        offset = DMat3::from_axis_angle(up, yaw.to_radians()) * offset;
        let right = up.cross(offset).normalize();
        let pitched = DMat3::from_axis_angle(right, -pitch.to_radians()) * offset;
        // Stay at least 1° away from the up axis, where the camera frame would flip.
        if pitched.normalize().dot(up).abs() < 1f64.to_radians().cos() {
            offset = pitched;
        }
        cam.look_from = cam.look_at + offset;
    }

    fn move_camera(&mut self, forward: f64, right: f64, upward: f64) {
        let cam = &mut self.scene.camera;
        let view = cam.look_at - cam.look_from;
        let dist = view.length();
        let f = view / dist;
        let r = f.cross(cam.up).normalize();
        let u = r.cross(f);
        let delta = dist * (forward * f + right * r + upward * u);
        cam.look_from += delta;
        cam.look_at += delta;
    }

    /// Puts the focus plane through the selected object's centre.
    fn focus_on_selected(&mut self) -> Effect {
        let Some(obj) = self.scene.objects.get(self.selected) else {
            return Effect::None;
        };
        let center = match &obj.shape {
            Shape::Sphere { center, .. } | Shape::Box { center, .. } => *center,
            Shape::Quad { q, u, v } => *q + 0.5 * (*u + *v),
            Shape::Mesh {
                mesh, instances, ..
            } if !instances.is_empty() => {
                // The copies' centre, from the mesh's own centroid: never the flattened copies
                // (2·10⁸ triangles for the forest).
                let sum: DVec3 = mesh.triangles.iter().flatten().copied().sum();
                let c = sum / (3 * mesh.triangles.len()).max(1) as f64;
                let at = |m: &glam::DMat4| m.transform_point3(c);
                instances.iter().map(at).sum::<DVec3>() / instances.len() as f64
            }
            Shape::Mesh { .. } => {
                let t = obj.shape.world_triangles();
                let sum: DVec3 = t.iter().flatten().copied().sum();
                sum / (3 * t.len()).max(1) as f64
            }
        };
        let cam = &mut self.scene.camera;
        let dir = (cam.look_at - cam.look_from).normalize();
        // Distance along the view axis: the focus plane is perpendicular to it.
        let along = (center - cam.look_from).dot(dir);
        if along <= 0.0 {
            self.say("the selected object is behind the camera");
            return Effect::None;
        }
        cam.focus_distance = Some(along);
        self.say(format!("focus distance {}", fmt_value(along)));
        Effect::SceneChanged
    }
}

/// A value for the status line: up to three decimals, no trailing zeros.
pub fn fmt_value(x: f64) -> String {
    if x.abs() >= 1000.0 {
        return format!("{x:.0}");
    }
    let s = format!("{x:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.into() }
}

/// The camera's distance to its target (for tests and the status line).
pub fn target_distance(scene: &Scene) -> f64 {
    (scene.camera.look_at - scene.camera.look_from).length()
}

/// Up vector of the camera (for tests).
pub fn camera_up(scene: &Scene) -> DVec3 {
    scene.camera.up
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ui::keys::action;
    use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyModifiers};

    /// The preview's state on built-in scene `name`.
    fn app_of(name: &str) -> App {
        App::new(
            Scene::load(name).unwrap(),
            "test adapter".into(),
            CellMode::Half,
        )
    }

    fn app() -> App {
        app_of("specular")
    }

    fn press(app: &mut App, c: KeyCode) -> Effect {
        let a = action(KeyEvent::new(c, KeyModifiers::NONE)).expect("bound key");
        app.apply(a)
    }

    #[test]
    fn tab_selects_objects_in_a_cycle() {
        let mut a = app();
        let n = a.scene.objects.len();
        assert_eq!(a.selected_label(), "ground");
        assert_eq!(press(&mut a, KeyCode::Tab), Effect::None);
        assert_eq!(a.selected_label(), "matte");
        press(&mut a, KeyCode::BackTab);
        press(&mut a, KeyCode::BackTab);
        assert_eq!(a.selected, n - 1);
    }

    #[test]
    fn material_keys_change_the_selected_object_and_reset() {
        let mut a = app();
        press(&mut a, KeyCode::Tab); // "matte", smoothness 0.95, specular 0
        press(&mut a, KeyCode::Char('3'));
        assert_eq!(a.param, Param::named("specular"));
        assert_eq!(press(&mut a, KeyCode::Char('+')), Effect::SceneChanged);
        assert_eq!(a.scene.objects[1].material.specular, 0.01);
        assert_eq!(press(&mut a, KeyCode::Char(']')), Effect::SceneChanged);
        assert_eq!(a.scene.objects[1].material.specular, 0.11);
        // Other objects are untouched.
        assert_eq!(a.scene.objects[2].material, a.original.objects[2].material);
        // At the bottom of the range a further step changes nothing and resets nothing.
        for _ in 0..20 {
            press(&mut a, KeyCode::Char('['));
        }
        assert_eq!(a.scene.objects[1].material.specular, 0.0);
        assert_eq!(press(&mut a, KeyCode::Char('-')), Effect::None);
    }

    #[test]
    fn smoothness_goes_negative_to_glass_and_colour_steps_in_srgb() {
        let mut a = app();
        press(&mut a, KeyCode::Char('1'));
        for _ in 0..20 {
            press(&mut a, KeyCode::Char('['));
        }
        assert_eq!(a.scene.objects[0].material.smoothness, -1.0);
        assert!(a.scene.objects[0].material.is_dielectric());
        press(&mut a, KeyCode::Char('6'));
        let before = a.value(Param::named("red")).unwrap();
        press(&mut a, KeyCode::Char(']'));
        assert!((a.value(Param::named("red")).unwrap() - (before + 0.1)).abs() < 2e-3);
    }

    #[test]
    fn a_pbr_material_is_edited_in_its_own_terms() {
        let mut a = app_of("pbr");
        press(&mut a, KeyCode::Tab); // "gold mirror": metallic 1, roughness 0
        // `1` and `2` are metallic and roughness here; the lecture's numbers are not shown.
        press(&mut a, KeyCode::Char('2'));
        assert_eq!(a.active_param(), Param::named("roughness"));
        assert_eq!(press(&mut a, KeyCode::Char(']')), Effect::SceneChanged);
        assert_eq!(a.scene.objects[1].material.roughness, 0.1);
        press(&mut a, KeyCode::Char('1'));
        assert_eq!(a.active_param(), Param::named("metallic"));
        assert_eq!(
            press(&mut a, KeyCode::Char('+')),
            Effect::None,
            "metallic is at 1"
        );
        press(&mut a, KeyCode::Char('-'));
        assert_eq!(a.scene.objects[1].material.metallic, 0.99);
        assert_eq!(a.value(Param::named("smoothness")), None);
        assert_eq!(a.value(Param::named("metallic")), Some(0.99f32 as f64));
        // `m` walks the pbr material's parameters and the camera's, never the lecture's.
        for _ in 0..12 {
            press(&mut a, KeyCode::Char('m'));
            assert!(
                a.value(a.active_param()).is_some(),
                "{:?}",
                a.active_param()
            );
        }
        // On a lecture material the same key is smoothness again.
        let mut b = app();
        press(&mut b, KeyCode::Char('1'));
        assert_eq!(b.active_param(), Param::named("smoothness"));
    }

    #[test]
    fn camera_keys_move_the_camera_and_reset() {
        let mut a = app();
        let d0 = target_distance(&a.scene);
        assert_eq!(press(&mut a, KeyCode::Left), Effect::SceneChanged);
        assert!(
            (target_distance(&a.scene) - d0).abs() < 1e-9,
            "orbit keeps the distance"
        );
        assert_ne!(a.scene.camera.look_from, a.original.camera.look_from);
        let at = a.scene.camera.look_at;
        press(&mut a, KeyCode::Char('i'));
        assert!(
            (target_distance(&a.scene) - d0).abs() < 1e-9,
            "moving moves the target too"
        );
        assert_ne!(a.scene.camera.look_at, at);
        let fov = a.scene.camera.vfov;
        press(&mut a, KeyCode::Char('z'));
        assert!(a.scene.camera.vfov < fov);
        // Pitching far up stops short of the up axis instead of flipping over it.
        for _ in 0..100 {
            press(&mut a, KeyCode::Up);
        }
        let off = (a.scene.camera.look_from - a.scene.camera.look_at).normalize();
        assert!(off.dot(camera_up(&a.scene).normalize()) < 1.0 - 1e-6);
    }

    #[test]
    fn aperture_focus_bounces_fov() {
        let mut a = app();
        press(&mut a, KeyCode::Char('9'));
        assert_eq!(a.scene.camera.aperture, 0.0);
        press(&mut a, KeyCode::Char('+'));
        assert!(a.scene.camera.aperture > 0.0);
        press(&mut a, KeyCode::Char('-'));
        press(&mut a, KeyCode::Char('-'));
        press(&mut a, KeyCode::Char('['));
        for _ in 0..30 {
            press(&mut a, KeyCode::Char('['));
        }
        assert_eq!(
            a.scene.camera.aperture, 0.0,
            "stepping down ends at a pinhole"
        );
        press(&mut a, KeyCode::Char('b'));
        let b = a.scene.render.max_bounces;
        press(&mut a, KeyCode::Char('+'));
        assert_eq!(a.scene.render.max_bounces, b + 1);
        press(&mut a, KeyCode::Char('v'));
        press(&mut a, KeyCode::Char(']'));
        assert_eq!(a.scene.camera.vfov, a.original.camera.vfov + 10.0);
        press(&mut a, KeyCode::Tab);
        assert_eq!(press(&mut a, KeyCode::Char('f')), Effect::SceneChanged);
        // "matte" at (-1.8, 0, -2.4), camera (0, 0.6, 1.2) looking at (0, 0, -2): the focus
        // plane goes through the centre, at its distance along the view axis.
        let cam = &a.scene.camera;
        let dir = (cam.look_at - cam.look_from).normalize();
        let along = (DVec3::new(-1.8, 0.0, -2.4) - cam.look_from).dot(dir);
        assert!(
            (cam.focus() - along).abs() < 1e-12,
            "{} vs {along}",
            cam.focus()
        );
    }

    #[test]
    fn revert_reset_save_write_quit() {
        let mut a = app();
        press(&mut a, KeyCode::Char('4'));
        press(&mut a, KeyCode::Char(']'));
        assert!(a.scene != a.original);
        assert_eq!(press(&mut a, KeyCode::Char('R')), Effect::SceneChanged);
        assert!(a.scene == a.original);
        assert_eq!(press(&mut a, KeyCode::Char('r')), Effect::Reset);
        assert_eq!(press(&mut a, KeyCode::Char('p')), Effect::SavePng);
        assert_eq!(press(&mut a, KeyCode::Char('w')), Effect::WriteScene);
        assert_eq!(press(&mut a, KeyCode::Char('c')), Effect::Relayout);
        assert_eq!(a.cells, CellMode::Quadrant);
        assert!(a.nee);
        assert_eq!(press(&mut a, KeyCode::Char('e')), Effect::SceneChanged);
        assert!(!a.nee);
        // Without a map the sky keys say so and change nothing.
        assert_eq!(press(&mut a, KeyCode::Char('.')), Effect::None);
        assert!(a.current_message().unwrap().contains("no environment map"));
        assert_eq!(press(&mut a, KeyCode::Char('q')), Effect::Quit);
        assert_eq!(press(&mut a, KeyCode::Esc), Effect::Quit);
        let ctrl_c = KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL);
        assert_eq!(a.apply(action(ctrl_c).unwrap()), Effect::Quit);
    }

    #[test]
    fn help_swallows_keys_until_closed() {
        let mut a = app();
        press(&mut a, KeyCode::Char('?'));
        assert_eq!(a.mode, Mode::Help);
        assert_eq!(press(&mut a, KeyCode::Left), Effect::None);
        assert!(a.scene == a.original);
        press(&mut a, KeyCode::Char('?'));
        assert_eq!(a.mode, Mode::Preview);
        press(&mut a, KeyCode::Char('?'));
        assert_eq!(
            press(&mut a, KeyCode::Esc),
            Effect::None,
            "Esc closes the help"
        );
        assert_eq!(a.mode, Mode::Preview);
    }

    #[test]
    fn values_print_compactly() {
        assert_eq!(fmt_value(0.95), "0.95");
        assert_eq!(fmt_value(1.0), "1");
        assert_eq!(fmt_value(-0.0001), "0");
        assert_eq!(fmt_value(1234.5), "1234");
    }

    #[test]
    fn sky_keys_turn_and_scale_the_map_and_restart() {
        let mut a = app_of("outdoor");
        assert_eq!(press(&mut a, KeyCode::Char('.')), Effect::SceneChanged);
        assert_eq!(press(&mut a, KeyCode::Char('.')), Effect::SceneChanged);
        assert_eq!(press(&mut a, KeyCode::Char(',')), Effect::SceneChanged);
        let e = a.scene.environment.as_ref().unwrap();
        assert_eq!(e.rotation, 195.0);
        assert_eq!(press(&mut a, KeyCode::Char('>')), Effect::SceneChanged);
        assert_eq!(press(&mut a, KeyCode::Char('>')), Effect::SceneChanged);
        assert_eq!(press(&mut a, KeyCode::Char('<')), Effect::SceneChanged);
        let e = a.scene.environment.as_ref().unwrap();
        assert!((e.intensity - 1.25).abs() < 1e-6, "{}", e.intensity);
        // Turning wraps at a full turn.
        for _ in 0..24 {
            press(&mut a, KeyCode::Char(','));
        }
        assert_eq!(a.scene.environment.as_ref().unwrap().rotation, 195.0);
    }

    #[test]
    fn d_switches_the_denoiser_off_and_back_to_its_mode() {
        use crate::denoise::Mode;
        let mut a = app();
        a.denoise = Mode::On;
        a.denoise_on = Mode::On;
        assert_eq!(
            press(&mut a, KeyCode::Char('d')),
            Effect::Denoise(Mode::Off)
        );
        assert_eq!(press(&mut a, KeyCode::Char('d')), Effect::Denoise(Mode::On));
        // Started off, `d` turns it to auto.
        a.denoise = Mode::Off;
        a.denoise_on = Mode::Auto;
        assert_eq!(
            press(&mut a, KeyCode::Char('d')),
            Effect::Denoise(Mode::Auto)
        );
        assert_eq!(a.scene, a.original, "the scene is untouched");
    }
}

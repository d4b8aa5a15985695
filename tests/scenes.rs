//! Scene files: every shipped scene loads (and is compiled in as a built-in), writes back to
//! the same scene, and every invalid scene in tests/scenes/invalid gives the message and
//! position its `# expect:` and `# at:` header lines state.

use std::path::Path;
use termtrace::scene::{BUILTIN_SCENES, Scene, SceneError, to_toml};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn every_shipped_scene_loads_and_is_builtin() {
    let mut names = Vec::new();
    for e in std::fs::read_dir(root().join("scenes")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            let scene = Scene::load_file(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            assert!(!scene.objects.is_empty(), "{} has no objects", p.display());
            let name = p.file_stem().unwrap().to_string_lossy().into_owned();
            let builtin = Scene::load(&name).unwrap();
            assert_eq!(
                builtin.objects, scene.objects,
                "builtin {name} differs from the file"
            );
            names.push(name);
        }
    }
    names.sort();
    let mut builtins: Vec<String> = BUILTIN_SCENES.iter().map(|(n, _)| n.to_string()).collect();
    builtins.sort();
    assert_eq!(names, builtins, "scenes/ and the built-in scenes differ");
}

#[test]
fn shipped_scenes_write_back_to_the_same_scene() {
    for (name, _) in BUILTIN_SCENES {
        let scene = Scene::load(name).unwrap();
        let text = to_toml(&scene);
        // Parsed with the same origin, so that relative mesh files resolve as before.
        let back = Scene::from_toml(&text, &scene.origin).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(back.camera, scene.camera, "{name}");
        assert_eq!(back.render, scene.render, "{name}");
        assert_eq!(back.sky, scene.sky, "{name}");
        assert_eq!(back.environment, scene.environment, "{name}");
        assert_eq!(back.materials, scene.materials, "{name}");
        assert_eq!(back.objects, scene.objects, "{name}");
    }
}

#[test]
fn weekend_has_the_books_layout() {
    let s = Scene::load("weekend").unwrap();
    let n = s.counts();
    assert!((450..=490).contains(&n.spheres), "{} spheres", n.spheres);
    assert_eq!((n.quads, n.boxes, n.meshes), (0, 0, 0));
    assert_eq!(s.camera.look_from, glam::DVec3::new(13.0, 2.0, 3.0));
    assert_eq!(s.camera.vfov, 20.0);
    assert_eq!(s.camera.focus(), 10.0);
    // A 0.6° defocus angle at focus distance 10: aperture = 2·10·tan(0.3°).
    let expected = 2.0 * 10.0 * 0.3f64.to_radians().tan();
    assert!((s.camera.aperture - expected).abs() < 1e-4);
}

#[test]
fn defaults_fill_what_a_scene_leaves_out() {
    let s = Scene::from_toml(
        "[[sphere]]\ncenter = [0, 0, -1]\nradius = 0.5\n\
         [[sphere]]\ncenter = [1, 0, -1]\nradius = 0.5\nsmoothness = -1\n",
        "t",
    )
    .unwrap();
    assert_eq!(s.render.width, 640);
    assert_eq!(s.render.max_bounces, 10);
    let (a, b) = (&s.objects[0].material, &s.objects[1].material);
    assert_eq!(a.color, glam::Vec3::splat(0.8));
    assert_eq!(
        (a.smoothness, a.absorption, a.specular, a.light, a.ior),
        (0.0, 0.0, 1.0, 0.0, 1.5)
    );
    assert_eq!(
        b.color,
        glam::Vec3::ONE,
        "a dielectric's default colour is white"
    );
    assert_eq!(s.camera.focus(), 1.0);
}

#[test]
fn inline_keys_override_a_named_material() {
    let s = Scene::from_toml(
        "[materials.glass]\nsmoothness = -1\nior = 1.5\n\
         [[sphere]]\ncenter = [0, 0, -1]\nradius = 0.5\nmaterial = \"glass\"\nior = 1.33\n",
        "t",
    )
    .unwrap();
    let m = &s.objects[0].material;
    assert_eq!((m.smoothness, m.ior), (-1.0, 1.33));
    assert_eq!(m.color, glam::Vec3::ONE);
}

struct Expectation {
    messages: Vec<String>,
    at: String,
}

fn expectation(text: &str) -> Expectation {
    let mut e = Expectation {
        messages: Vec::new(),
        at: String::new(),
    };
    for line in text.lines() {
        if let Some(m) = line.strip_prefix("# expect: ") {
            e.messages.push(m.to_string());
        } else if let Some(a) = line.strip_prefix("# at: ") {
            e.at = a.to_string();
        }
    }
    e
}

#[test]
fn invalid_scenes_give_the_expected_messages() {
    let dir = root().join("tests/scenes/invalid");
    let mut count = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        let text = std::fs::read_to_string(&p).unwrap();
        let exp = expectation(&text);
        assert!(
            !exp.messages.is_empty() && !exp.at.is_empty(),
            "{} lacks # expect / # at",
            p.display()
        );
        let err = Scene::load_file(&p).expect_err(&format!("{} loaded", p.display()));
        let shown = err.to_string();
        for m in &exp.messages {
            assert!(
                shown.contains(m.as_str()),
                "{}: message lacks `{m}`:\n{shown}",
                p.display()
            );
        }
        let SceneError::Invalid(diags) = &err else {
            panic!("{}: not a located error: {err}", p.display())
        };
        let first = &diags[0];
        let at = format!("{}:{}", first.line, first.column);
        assert!(
            at.starts_with(&exp.at),
            "{}: first error at {at}, expected {}:\n{shown}",
            p.display(),
            exp.at
        );
        let file = p.display().to_string();
        assert!(
            shown.contains(&format!("{file}:{at}")),
            "{}: message does not name file:line:col:\n{shown}",
            p.display()
        );
        count += 1;
    }
    assert!(count >= 15, "only {count} invalid scenes");
}

#[test]
fn a_missing_scene_names_the_builtins() {
    let e = Scene::load("no-such-scene").unwrap_err().to_string();
    assert!(
        e.contains("no-such-scene") && e.contains("weekend") && e.contains("cornell"),
        "{e}"
    );
}

#[test]
fn an_environment_map_writes_back_with_its_settings() {
    // A scene file beside a map, its intensity, rotation and visibility edited: the written
    // scene loads the same map with the same settings.
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        root().join("scenes/maps/quarry_01_1k.hdr"),
        dir.path().join("sky.hdr"),
    )
    .unwrap();
    let path = dir.path().join("lit.toml");
    std::fs::write(
        &path,
        "[sky]\nmap = \"sky.hdr\"\nrotation = 90\n[[sphere]]\ncenter = [0, 0, -1]\nradius = 0.5\n",
    )
    .unwrap();
    let mut scene = Scene::load_file(&path).unwrap();
    let e = scene.environment.as_mut().unwrap();
    assert_eq!(
        (e.file.as_str(), e.rotation, e.intensity, e.visible),
        ("sky.hdr", 90.0, 1.0, true)
    );
    e.intensity = 2.5;
    e.rotation = 195.0;
    e.visible = false;
    let text = to_toml(&scene);
    let back = Scene::from_toml(&text, &path.display().to_string()).unwrap();
    assert_eq!(back.environment, scene.environment);
    // --sky replaces the map and keeps the settings.
    let mut other = back.clone();
    other
        .set_sky_map(&root().join("scenes/maps/quarry_01_1k.hdr"))
        .unwrap();
    let o = other.environment.unwrap();
    assert!(std::path::Path::new(&o.file).is_absolute());
    assert_eq!((o.rotation, o.intensity, o.visible), (195.0, 2.5, false));
    assert!(
        Scene::load("basic")
            .unwrap()
            .set_sky_map(&dir.path().join("none.hdr"))
            .unwrap_err()
            .to_string()
            .contains("none.hdr")
    );
}

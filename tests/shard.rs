//! A render split into shards (disjoint ranges of every pixel's samples) and merged is the
//! render made whole, bit for bit, on both backends and in any order; a part missing, given
//! twice, from another render or corrupted is refused by name and nothing is written. The
//! command line as a job array runs it: the shard from SLURM_ARRAY_TASK_ID or
//! JOB_COMPLETION_INDEX.

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use termtrace::render::shard::{self, Header, Part};
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

const SPP: u32 = 11;

/// Shard `i` of `k` of `scene` at `SPP` samples, as `render --shard` makes it.
fn part(b: Backend, scene: &Scene, i: u32, k: u32) -> Part {
    let s = settings(20, 14, 6);
    let (first, end) = Header::range(i, k, SPP);
    let options = RenderOptions {
        first_sample: first,
        ..Default::default()
    };
    let mut r = Renderer::new(b, scene, s, options);
    r.render_spp(end - first);
    let termtrace::common::accum::Sums { even, odd, invalid } = r.exact_sums();
    Part {
        header: Header::new(scene, &s, SPP, (i, k), invalid),
        even,
        odd,
    }
}

fn named(parts: Vec<Part>) -> Vec<(PathBuf, Part)> {
    parts
        .into_iter()
        .map(|p| (PathBuf::from(format!("part-{}.tta", p.header.shard)), p))
        .collect()
}

#[test]
fn merged_shards_are_the_whole_render_bit_for_bit() {
    // 2, 3 and 7 shards of 11 samples (uneven: 7 shards of 1 or 2), merged in a shuffled
    // order, give the very words of the render made in one go; on the GPU adapter and on the
    // CPU tracer. The scene has glass, a light and light sampling, so paths of every kind.
    let scene = Scene::load("showcase").unwrap();
    for b in [Backend::Gpu(ctx()), Backend::Cpu] {
        let whole = part(b.clone(), &scene, 0, 1);
        assert!(whole.even.iter().any(|w| *w != 0));
        for k in [2u32, 3, 7] {
            let mut order: Vec<u32> = (0..k).collect();
            order.rotate_left(1);
            order.reverse();
            let parts: Vec<Part> = order
                .iter()
                .map(|&i| part(b.clone(), &scene, i, k))
                .collect();
            let merged = shard::merge(&named(parts)).unwrap();
            assert_eq!(merged.even, whole.even, "{} shards on {}", k, b.describe());
            assert_eq!(merged.odd, whole.odd, "{} shards on {}", k, b.describe());
            assert_eq!(merged.header.spp, SPP);
            assert_eq!(merged.header.invalid, whole.header.invalid);
        }
    }
}

#[test]
fn a_part_missing_repeated_foreign_or_corrupted_is_refused_by_name() {
    let scene = Scene::load("basic").unwrap();
    let parts: Vec<Part> = (0..3).map(|i| part(Backend::Cpu, &scene, i, 3)).collect();
    let all = named(parts.clone());
    assert!(shard::merge(&all).is_ok());
    // Missing.
    let e = shard::merge(&all[..2]).unwrap_err();
    assert!(e.contains("missing: 2"), "{e}");
    // Repeated.
    let mut twice = all.clone();
    twice.push((PathBuf::from("again.tta"), parts[1].clone()));
    let e = shard::merge(&twice).unwrap_err();
    assert!(
        e.contains("shard 1 of 3 is given twice: part-1.tta and again.tta"),
        "{e}"
    );
    // Another scene, another seed.
    let other = Scene::load("metal").unwrap();
    let mut foreign = all.clone();
    foreign[2] = (PathBuf::from("metal.tta"), part(Backend::Cpu, &other, 2, 3));
    let e = shard::merge(&foreign).unwrap_err();
    assert!(
        e.contains("metal.tta is not a part of the render") && e.contains("scene_hash"),
        "{e}"
    );
    let mut seeded = all.clone();
    seeded[0].1.header.seed = 99;
    let e = shard::merge(&seeded).unwrap_err();
    assert!(e.contains("seed = 99"), "{e}");
    // A part whose range is not its shard's.
    let mut shifted = all.clone();
    shifted[1].1.header.first_sample += 1;
    assert!(
        shard::merge(&shifted)
            .unwrap_err()
            .contains("not its share")
    );
    // Corrupted bytes, a cut-off file, another file altogether.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.tta");
    shard::write(&path, &parts[0]).unwrap();
    let back = shard::read(&path).unwrap();
    assert_eq!(
        (back.header, back.even, back.odd),
        (
            parts[0].header.clone(),
            parts[0].even.clone(),
            parts[0].odd.clone()
        )
    );
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[300] ^= 1;
    assert!(shard::parse(&bytes).unwrap_err().contains("checksum"));
    bytes.truncate(100);
    assert!(shard::parse(&bytes).is_err());
    assert!(
        shard::parse(b"P6 not a snapshot")
            .unwrap_err()
            .contains("not a termtrace snapshot")
    );
}

fn termtrace() -> Command {
    Command::new(env!("CARGO_BIN_EXE_termtrace"))
}

fn ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{cmd:?}: {err}");
    err
}

fn render_args<'a>(cmd: &'a mut Command, dir: &Path) -> &'a mut Command {
    cmd.current_dir(dir)
        .args([
            "render",
            "cornell",
            "--adapter",
            "cpu-native",
            "--width",
            "24",
        ])
        .args(["--height", "16", "--spp", "9", "-q"])
}

#[test]
fn a_job_array_renders_and_merges_as_the_whole_render() {
    // As a Slurm job array or a Kubernetes Indexed Job would: each task gets its index from
    // the scheduler's variable; the merged PNG is the whole render's PNG byte for byte.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (i, var) in [
        "SLURM_ARRAY_TASK_ID",
        "JOB_COMPLETION_INDEX",
        "SLURM_ARRAY_TASK_ID",
    ]
    .iter()
    .enumerate()
    {
        ok(render_args(&mut termtrace(), d)
            .args(["--shard", "3", "-o", &format!("part-{i}.tta")])
            .env_remove("SLURM_ARRAY_TASK_ID")
            .env_remove("JOB_COMPLETION_INDEX")
            .env(var, i.to_string()));
    }
    ok(termtrace().current_dir(d).args([
        "merge",
        "part-2.tta",
        "part-0.tta",
        "part-1.tta",
        "-o",
        "merged.png",
    ]));
    ok(render_args(&mut termtrace(), d).args(["-o", "whole.png"]));
    let merged = std::fs::read(d.join("merged.png")).unwrap();
    assert_eq!(merged, std::fs::read(d.join("whole.png")).unwrap());
    // A part missing: a clear message and no image.
    let out = termtrace()
        .current_dir(d)
        .args(["merge", "part-2.tta", "part-0.tta", "-o", "partial.png"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("missing: 1"), "{err}");
    assert!(!d.join("partial.png").exists());
    // An index outside the array, and no index at all.
    let out = render_args(&mut termtrace(), d)
        .args(["--shard", "3"])
        .env("SLURM_ARRAY_TASK_ID", "3")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--array=0-2"),
        "{err}"
    );
    let out = render_args(&mut termtrace(), d)
        .args(["--shard", "3"])
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("neither is set"),
        "{err}"
    );
}

#[test]
fn a_mesh_scene_hashes_the_same_in_every_process_and_by_its_triangles() {
    // Shards of one render are traced by separate processes, each loading the scene anew:
    // a mesh's hash must come from its triangles, not from where it lies in memory (two
    // loads in one process put it elsewhere too). A moved vertex changes the hash.
    let load = || termtrace::scene::load_scene("tests/gltf/Box/Box.gltf", None, None).unwrap();
    let (a, b) = (load(), load());
    assert_eq!(shard::scene_hash(&a), shard::scene_hash(&b));
    let mut moved = load();
    let termtrace::scene::Shape::Mesh { mesh, .. } = &mut moved.objects[0].shape else {
        panic!("the box is a mesh");
    };
    let mut triangles = mesh.triangles.clone();
    triangles[0][0].x += 1e-3;
    *mesh = std::sync::Arc::new(termtrace::scene::Mesh {
        triangles,
        skipped: mesh.skipped,
        uvs: mesh.uvs.clone(),
        normals: mesh.normals.clone(),
        tangents: mesh.tangents.clone(),
    });
    assert_ne!(shard::scene_hash(&a), shard::scene_hash(&moved));
}

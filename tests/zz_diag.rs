mod common;
use common::*;
use termtrace::denoise::denoise;
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

#[test]
fn diag() {
    let name = std::env::var("SCENE").unwrap_or("emissive".into());
    let spp: u32 = std::env::var("SPP")
        .map(|s| s.parse().unwrap())
        .unwrap_or(256);
    let scene = Scene::load(&name).unwrap();
    let mut fs = settings(64, 36, scene.render.max_bounces.min(8));
    fs.seed = termtrace::converge::reference::REFERENCE_SEED;
    let reference = snapshot_on(Backend::Cpu, &scene, fs, 4096, RenderOptions::default()).image();
    for run in 0..8u32 {
        fs.seed = 1 + run;
        let mut r = Renderer::new(Backend::Cpu, &scene, fs, RenderOptions::default());
        r.render_spp(spp);
        let snap = r.snapshot();
        let d = denoise(&snap.data.even, &snap.data.odd, r.guides());
        let shown = d.shown();
        let w = 64usize;
        let mut tile_true = vec![0.0f64; d.tiles.len()];
        let mut tile_true_raw = vec![0.0f64; d.tiles.len()];
        for p in 0..shown.len() {
            let t = (p / w / 16) * d.tiles_x + (p % w) / 16;
            for c in 0..3 {
                let rv = reference.pixels[p][c] as f64;
                tile_true[t] += (shown[p][c] as f64 - rv).powi(2) / (rv * rv + 0.01);
                tile_true_raw[t] += (d.raw[p][c] as f64 - rv).powi(2) / (rv * rv + 0.01);
            }
        }
        let tt: f64 = tile_true.iter().sum();
        let te: f64 = d.tile_shown.iter().sum();
        eprintln!(
            "run {run}: true {tt:.2} est {te:.2} ratio(rmse) {:.2}",
            (te / tt).sqrt()
        );
        for t in 0..d.tiles.len() {
            eprintln!(
                "  tile {t}: den {} reg {} | raw est {:.3} den est {:.3} shown xfit {:.3} | true shown {:.3} true raw {:.3}",
                d.tiles[t],
                d.tile_regression[t],
                d.tile_raw[t].rel,
                d.tile_denoised[t].rel,
                d.tile_shown[t],
                tile_true[t],
                tile_true_raw[t]
            );
        }
    }
}

//! The preview's resolve pass: the small image and noise estimate it makes on the GPU equal
//! what the host computes from the whole accumulation (`Snapshot::image`, the cells'
//! `downsample` in linear light, `Snapshot::noise_estimate`), up to f32 rounding.

mod common;
use common::*;
use termtrace::common::Resolved;
use termtrace::common::accum::Sums;
use termtrace::common::resolved::Doubt;
use termtrace::gpu::resolve::ResolvePass;
use termtrace::output::cells;
use termtrace::render::{Backend, RenderOptions, Renderer};
use termtrace::scene::Scene;

/// Every pixel of `got` within f32 rounding of `want`'s (1e-5 relative, 1e-8 absolute).
fn assert_close(got: &[[f32; 3]], want: &[[f32; 3]], what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: sizes");
    for (i, (a, b)) in got.iter().zip(want).enumerate() {
        let close = (0..3).all(|c| (a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1e-3));
        assert!(close, "{what}, pixel {i}: {a:?}, host {b:?}");
    }
}

#[test]
fn the_gpu_resolve_matches_the_host_downsample_and_noise_estimate() {
    let ctx = ctx();
    let scene = Scene::load("showcase").unwrap();
    for factor in [1, 2, 3] {
        let s = settings(12 * factor, 6 * factor, 6);
        let mut r = Renderer::new(ctx.clone(), &scene, s, RenderOptions::default());
        r.render_spp(6);
        // No sample of showcase is discarded: a known count in the counter shows that the
        // frame copies it back.
        let invalid = 40_000u64 * factor as u64 + (3 << 32);
        ctx.queue.write_buffer(
            &r.accumulation().unwrap().counters,
            0,
            bytemuck::bytes_of(&[invalid as u32, (invalid >> 32) as u32]),
        );
        let snap = r.snapshot();
        assert_eq!(snap.invalid_samples(), invalid);
        let host = cells::downsample(&snap.image(), factor);
        let mut pass = ResolvePass::new(&ctx);
        let slot = pass
            .request(&ctx, r.accumulation().unwrap(), (s.width, s.height), factor)
            .expect("a free slot");
        let gpu = take(&ctx, &mut pass, slot);
        assert_eq!((gpu.image.width, gpu.image.height), (12, 6));
        assert_close(
            &gpu.image.pixels,
            &host.pixels,
            &format!("factor {factor}, GPU"),
        );
        let (g, h) = (gpu.noise.unwrap(), snap.noise_estimate().unwrap());
        assert!(
            (g - h).abs() <= 1e-4 * h,
            "factor {factor}: noise {g} on the GPU, {h} on the host"
        );
        assert_eq!(gpu.invalid, invalid);
    }
}

/// Waits for `slot`'s frame.
fn take(ctx: &termtrace::gpu::GpuContext, pass: &mut ResolvePass, slot: usize) -> Resolved {
    loop {
        ctx.device
            .poll(wgpu::PollType::wait_indefinitely())
            .unwrap();
        if pass.ready(slot) {
            break pass.take(slot).expect("the readback maps");
        }
    }
}

#[test]
fn the_gpu_resolve_adds_another_devices_sums_exactly() {
    // The preview on several devices: the GPU traces samples 0..5, the CPU tracer 5..12 (its
    // sums uploaded with `set_extra`); the frame equals the host's of the words added exactly
    // (`shard::add_words`), up to f32 rounding, with the noise estimate of all 12 samples.
    // Cleared, the pass shows the GPU's own samples again.
    let ctx = ctx();
    let scene = Scene::load("showcase").unwrap();
    let s = settings(24, 12, 6);
    let mut gpu = Renderer::new(ctx.clone(), &scene, s, RenderOptions::default());
    gpu.render_spp(5);
    let mut cpu = Renderer::new(
        Backend::Cpu,
        &scene,
        s,
        RenderOptions {
            first_sample: 5,
            ..Default::default()
        },
    );
    cpu.render_spp(7);
    let mut total = gpu.exact_sums();
    let cpu_sums = cpu.exact_sums();
    total.add(&cpu_sums);
    let Sums { even, odd, invalid } = total;
    let (ce, co) = (cpu_sums.even, cpu_sums.odd);
    let mut pass = ResolvePass::new(&ctx);
    for factor in [1, 2] {
        let host = Resolved::from_sums(&even, &odd, (s.width, s.height), factor, invalid);
        pass.set_extra(&ctx, &ce, &co);
        let slot = pass
            .request(
                &ctx,
                gpu.accumulation().unwrap(),
                (s.width, s.height),
                factor,
            )
            .unwrap();
        let both = take(&ctx, &mut pass, slot);
        let what = format!("factor {factor}, both devices on the GPU");
        assert_close(&both.image.pixels, &host.image.pixels, &what);
        let (g, h) = (both.noise.unwrap(), host.noise.unwrap());
        assert!(
            (g - h).abs() <= 1e-4 * h,
            "noise {g} on the GPU, {h} on the host"
        );
        pass.clear_extra();
        let slot = pass
            .request(
                &ctx,
                gpu.accumulation().unwrap(),
                (s.width, s.height),
                factor,
            )
            .unwrap();
        let own = take(&ctx, &mut pass, slot);
        let g = gpu.exact_sums();
        let alone = Resolved::from_sums(&g.even, &g.odd, (s.width, s.height), factor, g.invalid);
        let what = format!("factor {factor}, cleared");
        assert_close(&own.image.pixels, &alone.image.pixels, &what);
        assert_ne!(own.image.pixels, both.image.pixels);
    }
}

#[test]
fn the_noise_estimate_waits_for_a_sample_in_each_half() {
    let ctx = ctx();
    let scene = Scene::load("basic").unwrap();
    let s = settings(8, 8, 4);
    let mut r = Renderer::new(ctx.clone(), &scene, s, RenderOptions::default());
    r.render_spp(1);
    let mut pass = ResolvePass::new(&ctx);
    let slot = pass
        .request(&ctx, r.accumulation().unwrap(), (8, 8), 1)
        .expect("a free slot");
    // A second request takes the other slot; a third finds none until one is taken.
    let other = pass
        .request(&ctx, r.accumulation().unwrap(), (8, 8), 1)
        .unwrap();
    assert_ne!(slot, other);
    assert!(
        pass.request(&ctx, r.accumulation().unwrap(), (8, 8), 1)
            .is_none()
    );
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .unwrap();
    let one = pass.take(slot).expect("landed");
    assert!(one.noise.is_none(), "one sample: no odd half yet");
    assert!(pass.take(other).is_some());
    assert!(pass.has_free_slot());
}

#[test]
fn the_cpu_tracers_frames_match_the_host_downsample_and_noise_estimate() {
    let scene = Scene::load("showcase").unwrap();
    for factor in [1, 2, 3] {
        let s = settings(12 * factor, 6 * factor, 6);
        let mut r = Renderer::new(
            termtrace::render::Backend::Cpu,
            &scene,
            s,
            RenderOptions::default(),
        );
        assert!(r.resolve_on_host(factor).unwrap().noise.is_none());
        r.render_spp(6);
        let snap = r.snapshot();
        let host = cells::downsample(&snap.image(), factor);
        let frame = r
            .resolve_on_host(factor)
            .expect("the CPU makes frames on the host");
        assert_eq!((frame.image.width, frame.image.height), (12, 6));
        let what = format!("factor {factor}, the CPU's frame");
        assert_close(&frame.image.pixels, &host.pixels, &what);
        let (f, h) = (frame.noise.unwrap(), snap.noise_estimate().unwrap());
        assert!(
            (f - h).abs() <= 1e-4 * h,
            "factor {factor}: noise {f}, host {h}"
        );
        assert!(frame.sigma.iter().all(|s| s.is_finite() && *s >= 0.0));
    }
}

#[test]
fn the_gpu_and_the_host_doubt_the_same_estimates() {
    // The resolve pass's sum of squared pixel terms gives the same doubt as the host's frame
    // of the same sums (`Resolved::from_sums`), and the figures behind it agree: at 2 spp
    // (one sample a half) every estimate is rough for its few samples; at 32 spp on the
    // firefly scene (a lamp of radius 0.01 that paths find by chance) at 24×12 pixels a few
    // fireflies hold the estimate, on showcase they do not. (The caustic scene was the
    // rough one until its glossy ball's highlight came in every sample: `Weighed::Mixed`.)
    let ctx = ctx();
    for (name, spp, want) in [
        ("showcase", 2, Some(Doubt::FewSamples)),
        ("showcase", 32, None),
        ("extreme/firefly", 32, Some(Doubt::FewPixels)),
    ] {
        let scene = Scene::load(name).unwrap();
        let s = settings(24, 12, 8);
        let mut r = Renderer::new(ctx.clone(), &scene, s, RenderOptions::default());
        r.render_spp(spp);
        let mut pass = ResolvePass::new(&ctx);
        let slot = pass
            .request(&ctx, r.accumulation().unwrap(), (s.width, s.height), 2)
            .expect("a free slot");
        let gpu = take(&ctx, &mut pass, slot);
        let sums = r.exact_sums();
        let host = Resolved::from_sums(&sums.even, &sums.odd, (s.width, s.height), 2, 0);
        assert_eq!(gpu.doubt, host.doubt, "{name} at {spp} spp");
        assert_eq!(host.doubt, want, "{name} at {spp} spp");
    }
}

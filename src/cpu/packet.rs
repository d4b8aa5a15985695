//! Eight rays walked through the BVH together in AVX lanes: the camera rays of eight
//! neighbouring pixels, which enter the same nodes, so that one node visit serves them all
//! (2.6× single rays on `weekend`'s camera rays; BENCHMARKS.md, "Packets"). Spheres only; the
//! hits are those of single rays bit for bit (tested), so the images do not change.

use super::bvh::{Bvh4, Tally, nearest_next, slots};
use super::intersect::{LANES, Ray, Sphere, safe_inverse};
use crate::bvh::wide::STACK;
use crate::common::arrays::REF_INDEX as INDEX;
use std::arch::x86_64::*;

/// Up to eight rays, structure of arrays; `active` the lanes that hold one.
struct Packet {
    o: [__m256; 3],
    d: [__m256; 3],
    inv: [__m256; 3],
    active: u32,
}

impl Packet {
    #[target_feature(enable = "avx")]
    fn new(rays: &[Option<Ray>; LANES]) -> Packet {
        let mut a = [[0.0f32; LANES]; 9];
        let mut active = 0;
        for (l, r) in rays.iter().enumerate() {
            let Some(r) = r else {
                a[6][l] = 1.0;
                a[7][l] = 1.0;
                a[8][l] = 1.0;
                continue;
            };
            let inv = safe_inverse(r.dir);
            for k in 0..3 {
                a[k][l] = r.origin[k];
                a[3 + k][l] = r.dir[k];
                a[6 + k][l] = inv[k];
            }
            active |= 1 << l;
        }
        // SAFETY: unaligned loads of eight floats from arrays of eight.
        let v = a.map(|x| unsafe { _mm256_loadu_ps(x.as_ptr()) });
        Packet {
            o: [v[0], v[1], v[2]],
            d: [v[3], v[4], v[5]],
            inv: [v[6], v[7], v[8]],
            active,
        }
    }
}

/// Entries of the packet walk's stack: node, lanes, nearest entry distance of those lanes.
type PacketStack = [(u32, u32, f32); STACK];

/// Walks packets of camera rays where the CPU has AVX (decided once).
pub struct Packets {
    stack: Box<PacketStack>,
}

impl Packets {
    /// None where the CPU lacks AVX.
    pub fn new() -> Option<Packets> {
        std::arch::is_x86_feature_detected!("avx").then(|| Packets {
            stack: Box::new([(0, 0, 0.0); STACK]),
        })
    }

    /// Every ray's nearest sphere before `t_far`: (t, BVH reference), or None. A node visit
    /// counts once in `tally` however many rays it serves.
    pub fn closest(
        &mut self,
        bvh: &Bvh4,
        spheres: &[Sphere],
        rays: &[Option<Ray>; LANES],
        t_far: f32,
        tally: &mut Tally,
    ) -> [Option<(f32, u32)>; LANES] {
        // SAFETY: `Packets` exists only where the CPU has AVX (`new`).
        unsafe { walk(bvh, spheres, rays, t_far, tally, &mut self.stack) }
    }
}

/// `Packets::closest` in AVX code throughout (its intrinsics inlined, not called).
#[target_feature(enable = "avx")]
fn walk(
    bvh: &Bvh4,
    spheres: &[Sphere],
    rays: &[Option<Ray>; LANES],
    t_far: f32,
    tally: &mut Tally,
    stack: &mut PacketStack,
) -> [Option<(f32, u32)>; LANES] {
    let p = Packet::new(rays);
    let mut t = [0.0f32; LANES];
    let mut hit = [u32::MAX; LANES];
    let mut tb = _mm256_set1_ps(t_far);
    closest8_spheres(bvh, spheres, &p, &mut tb, &mut hit, tally, stack);
    // SAFETY: eight floats stored into an array of eight.
    unsafe { _mm256_storeu_ps(t.as_mut_ptr(), tb) };
    std::array::from_fn(|l| (hit[l] != u32::MAX).then_some((t[l], hit[l])))
}

/// The nearest sphere of every active lane: `t_best` and `hit` per lane. A packet walk (Wald,
/// Slusallek, Benthin & Wagner, "Interactive Rendering with Coherent Ray Tracing", 2001): a
/// node is visited once for every lane whose ray enters it, the slab test of one child for
/// the eight rays one AVX operation per term, the children taken nearest first by the
/// nearest entry among their lanes (as `Bvh4::closest` orders them for one ray). Callers
/// check for AVX.
#[target_feature(enable = "avx")]
fn closest8_spheres(
    bvh: &Bvh4,
    spheres: &[Sphere],
    p: &Packet,
    t_best: &mut __m256,
    hit: &mut [u32; LANES],
    tally: &mut Tally,
    stack: &mut PacketStack,
) {
    if bvh.nodes.is_empty() || p.active == 0 {
        return;
    }
    let mut sp = 0usize;
    let (mut node, mut mask) = (0usize, p.active);
    let zero = _mm256_setzero_ps();
    let inf = _mm256_set1_ps(f32::INFINITY);
    loop {
        let n = &bvh.nodes[node];
        tally.visits += 1;
        let mut hitm = [0u32; 4];
        let mut near_min = [f32::INFINITY; 4];
        let b = [n.min_x, n.min_y, n.min_z, n.max_x, n.max_y, n.max_z].map(|v| v.to_array());
        for s in slots(n.valid as u32) {
            let t: [__m256; 6] = std::array::from_fn(|k| {
                _mm256_mul_ps(
                    _mm256_sub_ps(_mm256_set1_ps(b[k][s]), p.o[k % 3]),
                    p.inv[k % 3],
                )
            });
            let near = _mm256_max_ps(
                _mm256_max_ps(_mm256_min_ps(t[0], t[3]), _mm256_min_ps(t[1], t[4])),
                _mm256_max_ps(_mm256_min_ps(t[2], t[5]), zero),
            );
            let far = _mm256_min_ps(
                _mm256_min_ps(_mm256_max_ps(t[0], t[3]), _mm256_max_ps(t[1], t[4])),
                _mm256_min_ps(_mm256_max_ps(t[2], t[5]), *t_best),
            );
            let ok = _mm256_cmp_ps::<_CMP_LE_OQ>(near, far);
            let m = _mm256_movemask_ps(ok) as u32 & mask;
            hitm[s] = m;
            if m != 0 {
                let nm = _mm256_blendv_ps(inf, near, ok);
                let lo = _mm_min_ps(_mm256_castps256_ps128(nm), _mm256_extractf128_ps::<1>(nm));
                let lo = _mm_min_ps(lo, _mm_movehl_ps(lo, lo));
                let lo = _mm_min_ss(lo, _mm_shuffle_ps::<1>(lo, lo));
                near_min[s] = _mm_cvtss_f32(lo);
            }
        }
        for s in slots(n.leaves as u32) {
            if hitm[s] != 0 {
                let first = n.child[s] as usize;
                tally.tests += n.count[s] as u64;
                for &r in &bvh.refs[first..first + n.count[s] as usize] {
                    hit_sphere8(&spheres[(r & INDEX) as usize], p, hitm[s], r, t_best, hit);
                }
            }
        }
        let mut next: Option<(u32, u32, f32)> = None;
        let base = sp;
        for s in slots(n.valid as u32 & !(n.leaves as u32)) {
            if hitm[s] == 0 {
                continue;
            }
            let e = (n.child[s], hitm[s], near_min[s]);
            nearest_next(&mut next, e, &mut stack[..], base, &mut sp, |e| e.2);
        }
        if let Some(e) = next {
            (node, mask) = (e.0 as usize, e.1);
            continue;
        }
        if sp == 0 {
            return;
        }
        sp -= 1;
        (node, mask) = (stack[sp].0 as usize, stack[sp].1);
    }
}

/// `intersect::hit_sphere` for eight rays: the same operations in the same order, so the
/// same bits. Lanes in `mask` whose ray hits nearer than their `t_max` take the distance
/// and `r`.
#[target_feature(enable = "avx")]
#[inline]
fn hit_sphere8(
    s: &Sphere,
    p: &Packet,
    mask: u32,
    r_id: u32,
    t_max: &mut __m256,
    hit: &mut [u32; LANES],
) {
    let r = s.radius.abs();
    let rv = _mm256_set1_ps(r);
    let a = [s.anchor.x, s.anchor.y, s.anchor.z].map(|x| _mm256_set1_ps(x));
    let an = [s.anchor_normal.x, s.anchor_normal.y, s.anchor_normal.z].map(|x| _mm256_set1_ps(x));
    let (add, sub, mul) = (
        |x, y| _mm256_add_ps(x, y),
        |x, y| _mm256_sub_ps(x, y),
        |x, y| _mm256_mul_ps(x, y),
    );
    let dot = |x: &[__m256; 3], y: &[__m256; 3]| {
        add(add(mul(x[0], y[0]), mul(x[1], y[1])), mul(x[2], y[2]))
    };
    let g: [__m256; 3] = std::array::from_fn(|k| sub(p.o[k], a[k]));
    let f: [__m256; 3] = std::array::from_fn(|k| add(g[k], mul(rv, an[k])));
    let b = dot(&f, &p.d);
    let l: [__m256; 3] = std::array::from_fn(|k| sub(f[k], mul(b, p.d[k])));
    let ll = _mm256_sqrt_ps(dot(&l, &l));
    let disc = mul(sub(rv, ll), add(rv, ll));
    let c = add(dot(&g, &g), mul(_mm256_set1_ps(2.0 * r), dot(&g, &an)));
    let zero = _mm256_setzero_ps();
    let sq = _mm256_sqrt_ps(_mm256_max_ps(disc, zero));
    let neg_b = _mm256_xor_ps(b, _mm256_set1_ps(-0.0));
    let neg_sq = _mm256_xor_ps(sq, _mm256_set1_ps(-0.0));
    let q = sub(
        neg_b,
        _mm256_blendv_ps(sq, neg_sq, _mm256_cmp_ps::<_CMP_LT_OQ>(b, zero)),
    );
    let t0 = _mm256_div_ps(c, q);
    let (tn, tf) = (_mm256_min_ps(t0, q), _mm256_max_ps(t0, q));
    let valid = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GE_OQ>(disc, zero),
        _mm256_cmp_ps::<_CMP_NEQ_OQ>(q, zero),
    );
    let in_range = |t| {
        _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(t, zero),
            _mm256_cmp_ps::<_CMP_LT_OQ>(t, *t_max),
        )
    };
    let (near_ok, far_ok) = (in_range(tn), in_range(tf));
    let ok = _mm256_and_ps(valid, _mm256_or_ps(near_ok, far_ok));
    let bits = _mm256_movemask_ps(ok) as u32 & mask;
    if bits != 0 {
        let lanes = _mm256_castsi256_ps(_mm256_setr_epi32(
            -((bits & 1) as i32),
            -((bits >> 1 & 1) as i32),
            -((bits >> 2 & 1) as i32),
            -((bits >> 3 & 1) as i32),
            -((bits >> 4 & 1) as i32),
            -((bits >> 5 & 1) as i32),
            -((bits >> 6 & 1) as i32),
            -((bits >> 7 & 1) as i32),
        ));
        let t = _mm256_blendv_ps(tf, tn, near_ok);
        *t_max = _mm256_blendv_ps(*t_max, t, lanes);
        for (l, h) in hit.iter_mut().enumerate() {
            if bits >> l & 1 != 0 {
                *h = r_id;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::bvh::Stack;
    use crate::cpu::scene::CpuScene;
    use crate::cpu::trace::{SPHERES, T_FAR, hit_primitive, recorded};
    use std::time::Instant;

    /// The rays `scene` traces at 160×90 and `spp` samples per pixel (only the camera rays
    /// if `camera`), and the packets eight paths walked together would make of them: eight
    /// paths in the order the row loop traces them (one sample of eight neighbouring
    /// pixels), bounce by bounce.
    fn packets_of(
        name: &str,
        spp: u32,
        camera: bool,
    ) -> (CpuScene, Vec<Ray>, Vec<[Option<Ray>; LANES]>) {
        let (s, recorded) = recorded(name, 160, 90, spp);
        let mut paths: Vec<Vec<Ray>> = Vec::new();
        for (bounce, ray) in &recorded {
            if *bounce == 0 {
                paths.push(Vec::new());
            }
            paths.last_mut().unwrap().push(*ray);
        }
        let mut packets = Vec::new();
        for group in paths.chunks(LANES) {
            let depth = if camera {
                1
            } else {
                group.iter().map(Vec::len).max().unwrap()
            };
            for k in 0..depth {
                packets.push(std::array::from_fn(|l| {
                    group.get(l).and_then(|p| p.get(k)).copied()
                }));
            }
        }
        let rays = recorded
            .into_iter()
            .filter(|(bounce, _)| !camera || *bounce == 0)
            .map(|(_, r)| r)
            .collect();
        (s, rays, packets)
    }

    #[test]
    fn the_packet_walk_finds_what_single_rays_find_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("no AVX: nothing to compare");
            return;
        }
        let (s, _, packets) = packets_of("weekend", 4, false);
        let (mut tally, mut stack) = (Tally::default(), Stack::default());
        let mut walker = Packets::new().unwrap();
        let mut hits = 0;
        for rays in packets.iter().step_by(7) {
            let got = walker.closest(&s.bvh, &s.spheres, rays, T_FAR, &mut tally);
            for (ray, got) in rays.iter().zip(got) {
                let Some(ray) = ray else { continue };
                let want = s.bvh.closest(ray, T_FAR, &mut tally, &mut stack, |r, t| {
                    hit_primitive::<SPHERES>(&s, r, ray, t)
                });
                let bits = |h: Option<(f32, u32)>| h.map(|(t, r)| (t.to_bits(), r));
                assert_eq!(bits(want), bits(got));
                hits += want.is_some() as u32;
            }
        }
        assert!(hits > 1000, "only {hits} hits compared");
    }

    /// The measurement behind BENCHMARKS.md "Packets" and "Eight-wide nodes": `cargo test --release --lib
    /// packet_walk_speed -- --ignored --nocapture`. PKT_SCENE names another sphere scene,
    /// PKT_SPP the samples per pixel (default 8), PKT_CAMERA=1 keeps only the camera rays.
    #[test]
    #[ignore]
    fn packet_walk_speed() {
        let name = std::env::var("PKT_SCENE").unwrap_or("weekend".into());
        let spp = std::env::var("PKT_SPP").map_or(LANES as u32, |v| v.parse().unwrap());
        let camera = std::env::var("PKT_CAMERA").is_ok();
        let (s, rays, packets) = packets_of(&name, spp, camera);
        let (mut tally, mut stack) = (Tally::default(), Stack::default());
        let runs = 5;
        let start = Instant::now();
        for _ in 0..runs {
            for ray in &rays {
                std::hint::black_box(s.bvh.closest(ray, T_FAR, &mut tally, &mut stack, |r, t| {
                    hit_primitive::<SPHERES>(&s, r, ray, t)
                }));
            }
        }
        let single = start.elapsed().as_secs_f64() / runs as f64;
        // The same rays alone through the eight-wide nodes (`cpu::bvh8`).
        assert!(std::arch::is_x86_feature_detected!("avx"), "no AVX");
        let b8 = crate::cpu::bvh8::Bvh8::new(&s.bvh);
        let mut stack8 = crate::cpu::bvh8::Stack8::default();
        let mut tally8 = Tally::default();
        let start = Instant::now();
        for _ in 0..runs {
            for ray in &rays {
                // SAFETY: AVX is present (asserted above).
                std::hint::black_box(unsafe {
                    b8.closest(&s.bvh.refs, ray, T_FAR, &mut tally8, &mut stack8, |r, t| {
                        hit_primitive::<SPHERES>(&s, r, ray, t)
                    })
                });
            }
        }
        let wide8 = start.elapsed().as_secs_f64() / runs as f64;
        eprintln!(
            "{name}: eight-wide nodes ({} of them) {:.1} ns/ray, {:.2} nodes/ray",
            b8.node_count(),
            wide8 * 1e9 / rays.len() as f64,
            tally8.visits as f64 / (runs * rays.len()) as f64
        );
        let single_visits = tally.visits as f64 / (runs * rays.len()) as f64;
        let mut tally = Tally::default();
        let mut walker = Packets::new().expect("AVX");
        let start = Instant::now();
        for _ in 0..runs {
            for p in &packets {
                std::hint::black_box(walker.closest(&s.bvh, &s.spheres, p, T_FAR, &mut tally));
            }
        }
        let packed = start.elapsed().as_secs_f64() / runs as f64;
        let n = (runs * packets.len()) as f64;
        let lanes = packets.iter().flatten().filter(|r| r.is_some()).count();
        eprintln!(
            "{name}: {} rays; single rays {:.1} ns/ray, {single_visits:.2} nodes/ray; \
             packets {:.1} ns/ray, {:.2} nodes and {:.2} sphere tests per packet, {:.2} rays per packet",
            rays.len(),
            single * 1e9 / rays.len() as f64,
            packed * 1e9 / rays.len() as f64,
            tally.visits as f64 / n,
            tally.tests as f64 / n,
            lanes as f64 / packets.len() as f64,
        );
    }
}

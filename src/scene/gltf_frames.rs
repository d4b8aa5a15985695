//! The shading frames of a glTF (or OBJ) primitive: each kept triangle's corner normals (the
//! file's `NORMAL`, or none: the tracers then use the flat normal, as glTF asks) and, for a
//! normal-mapped one, tangents (the file's `TANGENT`, else generated with MikkTSpace, as glTF
//! requires, through `bevy_mikktspace`), brought from the file's coordinates into world
//! space. A primitive without a normal map takes the normals alone: smooth shading.

use glam::{DMat3, DVec3};

/// One triangle's corner normals and tangents (`w`: the bitangent's sign), zero where unknown.
pub type Frame = ([[f32; 3]; 3], [[f32; 4]; 3]);

/// The frames of the triangles `tris` (vertex indices, as the file winds them) of a primitive
/// with `positions` (file coordinates), optional `normals` and `tangents` per vertex, and
/// texture coordinates `uvs` (per vertex; empty: all (0, 0)); `world` is the node's linear
/// part. Non-finite input reads as zero.
pub fn frames(
    tris: &[[u32; 3]],
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    tangents: &[[f32; 4]],
    uvs: &[[f32; 2]],
    world: DMat3,
) -> Vec<Frame> {
    let finite3 = |v: [f32; 3]| {
        if v.iter().all(|x| x.is_finite()) {
            v
        } else {
            [0.0; 3]
        }
    };
    let at = |i: u32| i as usize;
    let corner_normals: Vec<[[f32; 3]; 3]> = tris
        .iter()
        .map(|t| t.map(|i| normals.get(at(i)).copied().map_or([0.0; 3], finite3)))
        .collect();
    let corner_tangents: Vec<[[f32; 4]; 3]> = if tangents.len() >= positions.len() {
        tris.iter()
            .map(|t| {
                t.map(|i| {
                    let v = tangents[at(i)];
                    if v.iter().all(|x| x.is_finite()) {
                        v
                    } else {
                        [0.0; 4]
                    }
                })
            })
            .collect()
    } else {
        mikktspace(tris, positions, &corner_normals, uvs)
    };
    // Normals by the inverse transpose, tangents by the matrix; a mirroring matrix turns the
    // bitangent over (B = N × T · w).
    let normal_m = world.inverse().transpose();
    let flip = if world.determinant() < 0.0 { -1.0 } else { 1.0 };
    let unit = |v: DVec3| {
        let u = v.normalize_or_zero();
        [u.x as f32, u.y as f32, u.z as f32]
    };
    corner_normals
        .iter()
        .zip(&corner_tangents)
        .map(|(n, t)| {
            (
                n.map(|n| unit(normal_m * DVec3::from(n.map(f64::from)))),
                t.map(|t| {
                    let [x, y, z] = unit(world * DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64));
                    let w = if t[3] < 0.0 { -flip } else { flip };
                    [
                        x,
                        y,
                        z,
                        if x == 0.0 && y == 0.0 && z == 0.0 {
                            0.0
                        } else {
                            w
                        },
                    ]
                }),
            )
        })
        .collect()
}

/// The corner normals of the triangles `tris` alone (smooth shading without a normal map),
/// in world space as [`frames`] makes them, the corners in the order the importer keeps
/// (`mirrored`: a mirroring transform's, whose triangles are wound the other way); empty
/// where the file has no normals.
pub fn normals_only(
    tris: &[[u32; 3]],
    normals: &[[f32; 3]],
    world: DMat3,
    mirrored: bool,
) -> Vec<[[f32; 3]; 3]> {
    if normals.is_empty() {
        return Vec::new();
    }
    let normal_m = world.inverse().transpose();
    tris.iter()
        .map(|&[a, b, c]| {
            let t = if mirrored { [a, c, b] } else { [a, b, c] };
            t.map(|i| {
                let n = normals.get(i as usize).copied().unwrap_or([0.0; 3]);
                if n.iter().all(|x| x.is_finite()) {
                    let u = (normal_m * DVec3::from(n.map(f64::from))).normalize_or_zero();
                    [u.x as f32, u.y as f32, u.z as f32]
                } else {
                    [0.0; 3]
                }
            })
        })
        .collect()
}

/// MikkTSpace tangents of the triangles (Mikkelsen, "Simulation of Wrinkled Surfaces
/// Revisited", 2008; the algorithm glTF 2.0 names for meshes without tangents). A corner
/// without a normal takes its face's flat one; a corner MikkTSpace leaves without a value
/// (a degenerate face with no neighbour) is zero.
fn mikktspace(
    tris: &[[u32; 3]],
    positions: &[[f32; 3]],
    normals: &[[[f32; 3]; 3]],
    uvs: &[[f32; 2]],
) -> Vec<[[f32; 4]; 3]> {
    struct Faces<'a> {
        tris: &'a [[u32; 3]],
        positions: &'a [[f32; 3]],
        normals: Vec<[[f32; 3]; 3]>,
        uvs: &'a [[f32; 2]],
        out: Vec<[[f32; 4]; 3]>,
    }
    impl bevy_mikktspace::Geometry for Faces<'_> {
        fn num_faces(&self) -> usize {
            self.tris.len()
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.positions[self.tris[face][vert] as usize]
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.normals[face][vert]
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            let uv = self
                .uvs
                .get(self.tris[face][vert] as usize)
                .copied()
                .unwrap_or([0.0; 2]);
            if uv.iter().all(|x| x.is_finite()) {
                uv
            } else {
                [0.0; 2]
            }
        }
        fn set_tangent(
            &mut self,
            ts: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            // MikkTSpace's bitangent follows increasing v; glTF's v runs down the image while
            // its normal maps' green is up, so the sign is negated (as three.js does for
            // glTF: `computeMikkTSpaceTangents(…, negateSign = true)`).
            self.out[face][vert] = ts.map_or([0.0; 4], |t| {
                let [x, y, z, w] = t.tangent_encoded();
                [x, y, z, -w]
            });
        }
    }
    let flat = |t: &[u32; 3]| {
        let p = t.map(|i| DVec3::from(positions[i as usize].map(f64::from)));
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        [n.x as f32, n.y as f32, n.z as f32]
    };
    let normals = tris
        .iter()
        .zip(normals)
        .map(|(t, n)| {
            let f = flat(t);
            n.map(|c| if c == [0.0; 3] { f } else { c })
        })
        .collect();
    let mut faces = Faces {
        tris,
        positions,
        normals,
        uvs,
        out: vec![[[0.0; 4]; 3]; tris.len()],
    };
    // The crate's error type has no variant: generation cannot fail.
    let _ = bevy_mikktspace::generate_tangents(&mut faces);
    faces.out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square in the xz plane facing +y, u along +x and v along +z: the tangent is +x, and
    /// the bitangent N × T · w must point up the image, where v falls: −z. (0,1,0) × (1,0,0)
    /// = (0,0,−1), so w = +1.
    #[test]
    fn generated_tangents_follow_the_texture_coordinates() {
        let positions = [[0., 0., 0.], [1., 0., 0.], [0., 0., 1.], [1., 0., 1.]];
        let uvs = [[0., 0.], [1., 0.], [0., 1.], [1., 1.]];
        // Wound counter-clockwise seen from +y.
        let tris = [[0, 2, 1], [1, 2, 3]];
        let f = frames(&tris, &positions, &[], &[], &uvs, DMat3::IDENTITY);
        for (n, t) in &f {
            assert_eq!(*n, [[0.0; 3]; 3], "no file normals: zero");
            for c in t {
                assert!((c[0] - 1.0).abs() < 1e-6 && c[1].abs() < 1e-6 && c[2].abs() < 1e-6);
                assert_eq!(c[3], 1.0, "{c:?}");
            }
        }
        // A mirror in x turns the tangent to −x and the bitangent's sign over.
        let m = frames(
            &tris,
            &positions,
            &[[0., 1., 0.]; 4],
            &[],
            &uvs,
            DMat3::from_diagonal(DVec3::new(-1.0, 1.0, 1.0)),
        );
        for (n, t) in &m {
            assert_eq!(*n, [[0.0, 1.0, 0.0]; 3]);
            for c in t {
                assert!((c[0] + 1.0).abs() < 1e-6, "{c:?}");
                assert_eq!(c[3], -1.0);
            }
        }
    }

    #[test]
    fn file_tangents_are_kept_and_bad_ones_are_zero() {
        let positions = [[0., 0., 0.], [1., 0., 0.], [0., 1., 0.]];
        let tangents = [[0., 1., 0., 1.], [f32::NAN, 0., 0., 1.], [0., 2., 0., -1.]];
        let normals = [[0., 0., 2.], [0., 0., 1.], [f32::INFINITY, 0., 1.]];
        let f = frames(
            &[[0, 1, 2]],
            &positions,
            &normals,
            &tangents,
            &[],
            DMat3::from_diagonal(DVec3::splat(3.0)),
        );
        let (n, t) = f[0];
        assert_eq!(n, [[0., 0., 1.], [0., 0., 1.], [0., 0., 0.]]);
        assert_eq!(t, [[0., 1., 0., 1.], [0.; 4], [0., 1., 0., -1.]]);
    }
}

//! Mitsuba's built-in shapes as triangle meshes in their local frames, and placing a
//! mesh in the world: `rectangle` ([−1, 1]² in z = 0, facing +z), `cube` ([−1, 1]³,
//! facing out) and `sphere` (an icosphere of 20,480 triangles on the exact sphere,
//! facing out; its area is 0.1 % below the true sphere's).

use glam::{Mat4, Vec3};

/// Positions and triangles.
pub(crate) type Mesh = (Vec<Vec3>, Vec<[u32; 3]>);

/// The unit rectangle, counter-clockwise seen from +z.
pub(crate) fn rectangle() -> Mesh {
    let p = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    (p, vec![[0, 1, 2], [0, 2, 3]])
}

/// The cube [−1, 1]³, every face wound to face outward.
pub(crate) fn cube() -> Mesh {
    let (mut p, mut t) = (Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let n = Vec3::from_array(std::array::from_fn(|i| if i == axis { sign } else { 0.0 }));
            // Two tangents with u × v = n.
            let u = Vec3::from_array(std::array::from_fn(|i| if i == (axis + 1) % 3 { 1.0 } else { 0.0 }));
            let v = n.cross(u);
            let base = p.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                p.push(n + u * a + v * b);
            }
            t.push([base, base + 1, base + 2]);
            t.push([base, base + 2, base + 3]);
        }
    }
    (p, t)
}

/// A sphere of `radius` about `center`: an icosahedron subdivided 5 times.
pub(crate) fn sphere(center: Vec3, radius: f32) -> Mesh {
    let (p, t) = crate::geometry::icosphere(5);
    (p.into_iter().map(|v| center + v * radius).collect(), t)
}

/// Moves a mesh into the world. `keep_facing`: built-in shapes keep facing the way
/// their normals transform (Mitsuba transforms them by the inverse transpose), so a
/// mirroring transform reverses their winding. `flip` reverses it once more
/// (`flip_normals`).
pub(crate) fn place(mesh: Mesh, m: Mat4, keep_facing: bool, flip: bool) -> Mesh {
    let (p, mut t) = mesh;
    let p: Vec<Vec3> = p.into_iter().map(|v| m.transform_point3(v)).collect();
    let mirrored = keep_facing && m.determinant() < 0.0;
    if mirrored != flip {
        t.iter_mut().for_each(|tri| tri.swap(1, 2));
    }
    (p, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::triangle_normal;

    fn outward(mesh: &Mesh, center: Vec3) -> bool {
        mesh.1.iter().all(|t| {
            let [a, b, c] = t.map(|i| mesh.0[i as usize]);
            triangle_normal(a, b, c).dot((a + b + c) / 3.0 - center) > 0.0
        })
    }

    #[test]
    fn built_in_shapes_face_the_way_mitsuba_says() {
        let r = rectangle();
        assert!(r.1.iter().all(|t| {
            let [a, b, c] = t.map(|i| r.0[i as usize]);
            triangle_normal(a, b, c).normalize() == Vec3::Z
        }));
        assert!(outward(&cube(), Vec3::ZERO));
        let s = sphere(Vec3::new(1.0, 2.0, 3.0), 0.5);
        assert_eq!(s.1.len(), 20 * 4usize.pow(5));
        assert!(outward(&s, Vec3::new(1.0, 2.0, 3.0)));
        // Area within 0.2 % of the sphere's.
        let area: f32 =
            s.1.iter()
                .map(|t| 0.5 * triangle_normal(s.0[t[0] as usize], s.0[t[1] as usize], s.0[t[2] as usize]).length())
                .sum();
        let exact = 4.0 * std::f32::consts::PI * 0.25;
        assert!((area / exact - 1.0).abs() < 2e-3, "{area} vs {exact}");
        // A mirror keeps built-in shapes facing out; flip_normals turns them in.
        let mirror = Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        assert!(outward(&place(cube(), mirror, true, false), Vec3::ZERO));
        assert!(!outward(&place(cube(), Mat4::IDENTITY, true, true), Vec3::ZERO));
    }
}

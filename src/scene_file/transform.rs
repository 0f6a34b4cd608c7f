//! Mitsuba `<transform>` elements: `matrix`, `lookat`, `translate`, `rotate`, `scale`,
//! composed in document order as Mitsuba does (each operation is applied after the
//! previous ones: `M = op · M`).

use super::xml::Node;
use glam::{DMat3, DMat4, DVec3};

/// Parses numbers separated by commas and/or whitespace.
pub(crate) fn numbers(s: &str) -> Result<Vec<f64>, String> {
    s.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().map_err(|_| format!("'{t}' is not a number")))
        .collect()
}

/// Parses a single number.
pub(crate) fn number(s: &str) -> Result<f64, String> {
    let v = numbers(s)?;
    match v.as_slice() {
        [x] => Ok(*x),
        _ => Err(format!("expected one number, found '{s}'")),
    }
}

/// A 3-vector from `value="x, y, z"` or from the attributes `x`, `y`, `z` (each defaulting
/// to `default`). `value` with a single number gives `(v, v, v)` if `splat`.
pub(crate) fn vector3(n: &Node, default: f64, splat: bool) -> Result<DVec3, String> {
    if let Some(v) = n.attr("value") {
        let v = numbers(v)?;
        return match v.as_slice() {
            [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
            [x] if splat => Ok(DVec3::splat(*x)),
            _ => Err(format!("<{}> value needs 3 numbers", n.tag)),
        };
    }
    let c = |k: &str| n.attr(k).map(number).unwrap_or(Ok(default));
    Ok(DVec3::new(c("x")?, c("y")?, c("z")?))
}

fn vec_attr(n: &Node, key: &str) -> Result<DVec3, String> {
    let s = n.attr(key).ok_or_else(|| format!("<{}> lacks the attribute '{key}'", n.tag))?;
    let v = numbers(s)?;
    match v.as_slice() {
        [x, y, z] if [x, y, z].iter().all(|c| c.is_finite()) => Ok(DVec3::new(*x, *y, *z)),
        [_, _, _] => Err(format!("<{}> attribute '{key}' is not finite: '{s}'", n.tag)),
        _ => Err(format!("<{}> attribute '{key}' needs 3 numbers, found '{s}'", n.tag)),
    }
}

/// Mitsuba's look-at matrix: columns (left, up', forward, origin) with
/// `forward = normalize(target − origin)`, `left = normalize(up × forward)`,
/// `up' = forward × left`.
pub fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> Result<DMat4, String> {
    let dir = (target - origin).normalize_or_zero();
    if dir == DVec3::ZERO || !dir.is_finite() {
        return Err("lookat: target equals origin".into());
    }
    let left = up.cross(dir).normalize_or_zero();
    if left == DVec3::ZERO || !left.is_finite() {
        return Err("lookat: 'up' is zero or parallel to the viewing direction".into());
    }
    let new_up = dir.cross(left);
    Ok(DMat4::from_cols(left.extend(0.0), new_up.extend(0.0), dir.extend(0.0), origin.extend(1.0)))
}

/// Parses the operations of a `<transform>` element into one matrix; `Err((line, message))`.
pub(crate) fn parse_transform(t: &Node) -> Result<DMat4, (usize, String)> {
    let mut m = DMat4::IDENTITY;
    for op in &t.children {
        let e = |msg: String| (op.line, msg);
        let next = match op.tag.as_str() {
            "translate" => DMat4::from_translation(vector3(op, 0.0, false).map_err(e)?),
            "scale" => {
                let s = vector3(op, 1.0, true).map_err(e)?;
                DMat4::from_scale(s)
            }
            "rotate" => {
                let axis = vector3(op, 0.0, false).map_err(e)?;
                let angle = op.attr("angle").ok_or_else(|| e("<rotate> lacks 'angle' (degrees)".into())).and_then(|a| number(a).map_err(e))?;
                let axis = axis.normalize_or_zero();
                if axis == DVec3::ZERO {
                    return Err(e("<rotate> axis is zero".into()));
                }
                DMat4::from_axis_angle(axis, angle.to_radians())
            }
            "matrix" => {
                let s = op.attr("value").ok_or_else(|| e("<matrix> lacks 'value'".into()))?;
                let v = numbers(s).map_err(e)?;
                match v.len() {
                    // Row-major in the file; glam is column-major.
                    16 => DMat4::from_cols_slice(&v).transpose(),
                    9 => DMat4::from_mat3(DMat3::from_cols_slice(&v).transpose()),
                    n => return Err(e(format!("<matrix> needs 16 (or 9) numbers, found {n}"))),
                }
            }
            "lookat" | "lookAt" => {
                let origin = vec_attr(op, "origin").map_err(e)?;
                let target = vec_attr(op, "target").map_err(e)?;
                let up = if op.attr("up").is_some() { vec_attr(op, "up").map_err(e)? } else { DVec3::Y };
                look_at(origin, target, up).map_err(e)?
            }
            other => return Err(e(format!("unsupported transform operation <{other}> (supported: translate, rotate, scale, matrix, lookat)"))),
        };
        if !next.is_finite() {
            return Err(e(format!("<{}> is not finite (NaN or infinite values)", op.tag)));
        }
        m = next * m;
        if !m.is_finite() {
            return Err(e(format!("the transform overflows at <{}> (not finite)", op.tag)));
        }
    }
    // A singular linear part flattens space: shapes lose their area and normals (the
    // inverse transpose) are undefined; a camera or light has no frame.
    let linear = DMat3::from_mat4(m);
    let det = linear.determinant();
    if det.is_infinite() {
        return Err((t.line, format!("the transform's scale overflows (determinant {det:e})")));
    }
    if !det.is_normal() || !linear.inverse().is_finite() {
        return Err((t.line, format!("the transform is singular (determinant {det:e}): it maps space onto a plane, line or point")));
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_file::xml::parse;
    use std::path::Path;

    fn tr(x: &str) -> DMat4 {
        parse_transform(&parse(x, Path::new("t")).unwrap()).unwrap()
    }

    #[test]
    fn document_order_composition() {
        // scale then translate: the point (1,0,0) goes to (2,0,0) then (2,5,0).
        let m = tr(r#"<transform name="to_world"><scale value="2"/><translate y="5"/></transform>"#);
        assert!((m.transform_point3(DVec3::X) - DVec3::new(2.0, 5.0, 0.0)).length() < 1e-12);
        let m = tr(r#"<transform><translate y="5"/><rotate x="1" angle="90"/></transform>"#);
        assert!((m.transform_point3(DVec3::ZERO) - DVec3::new(0.0, 0.0, 5.0)).length() < 1e-12);
        let m = tr(r#"<transform><matrix value="1 0 0 3  0 1 0 4  0 0 1 5  0 0 0 1"/></transform>"#);
        assert!((m.transform_point3(DVec3::ZERO) - DVec3::new(3.0, 4.0, 5.0)).length() < 1e-12);
    }

    #[test]
    fn lookat_matches_mitsuba() {
        let m = look_at(DVec3::new(0.0, 1.0, 6.8), DVec3::new(0.0, 1.0, 0.0), DVec3::Y).unwrap();
        // camera +z forward, +y up, +x left (world -x when looking along -z).
        assert!((m.transform_vector3(DVec3::Z) - DVec3::NEG_Z).length() < 1e-12);
        assert!((m.transform_vector3(DVec3::X) - DVec3::NEG_X).length() < 1e-12);
        assert!(look_at(DVec3::ZERO, DVec3::Y, DVec3::Y).is_err());
    }
}

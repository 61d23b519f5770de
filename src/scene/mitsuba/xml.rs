//! The generic layer of Mitsuba 3's XML format: `<default>` values and `$name`
//! substitution, typed properties (`float`, `integer`, `boolean`, `string`, `rgb`,
//! `spectrum`, `point`, `vector`, `transform`), transforms, and errors that name the
//! element and its line. Which properties a plugin takes is decided in `mod.rs`;
//! every property a plugin does not read is an error ([`Props::finish`]).

use crate::error::{Error, Location, Result};
use glam::{DMat4, DVec3, Mat4, Vec3};
use roxmltree::Node;
use std::collections::HashMap;
use std::path::Path;

/// The parsed document and what errors need to name places in it.
pub(crate) struct Doc<'a> {
    pub path: &'a Path,
    pub text: &'a str,
    pub defaults: HashMap<String, String>,
}

/// A typed property value.
#[derive(Clone, Debug)]
pub(crate) enum Value {
    Number(f64),
    Bool(bool),
    Text(String),
    Color(Vec3),
    Point(Vec3),
    Transform(Mat4),
}

impl<'a> Doc<'a> {
    /// The 1-based line where `node` starts.
    pub fn line(&self, node: Node) -> usize {
        crate::scene::desc::line_of(self.text, node.range().start)
    }

    /// An error at `node`, naming it as `<tag type="...">`.
    pub fn err(&self, node: Node, msg: impl std::fmt::Display) -> Error {
        Error::SceneFile { at: Location::new(self.path, self.line(node)), msg: format!("{}: {msg}", describe(node)) }
    }

    /// Attribute `name` with `$default` references substituted.
    pub fn attr(&self, node: Node, name: &str) -> Result<Option<String>> {
        let Some(raw) = node.attribute(name) else { return Ok(None) };
        if !raw.contains('$') {
            return Ok(Some(raw.to_string()));
        }
        let mut out = String::new();
        let mut rest = raw;
        while let Some(i) = rest.find('$') {
            out.push_str(&rest[..i]);
            let tail = &rest[i + 1..];
            let end = tail.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(tail.len());
            let key = &tail[..end];
            let value = self
                .defaults
                .get(key)
                .ok_or_else(|| self.err(node, format!("${key} has no <default name=\"{key}\" .../>")))?;
            out.push_str(value);
            rest = &tail[end..];
        }
        out.push_str(rest);
        Ok(Some(out))
    }

    /// A required attribute.
    pub fn need(&self, node: Node, name: &str) -> Result<String> {
        self.attr(node, name)?.ok_or_else(|| self.err(node, format!("attribute '{name}' is missing")))
    }

    fn numbers(&self, node: Node, text: &str) -> Result<Vec<f64>> {
        text.split(|c: char| c == ',' || c.is_whitespace())
            .filter(|w| !w.is_empty())
            .map(|w| {
                let v: f64 = w.parse().map_err(|_| self.err(node, format!("'{w}' is not a number")))?;
                if v.is_finite() { Ok(v) } else { Err(self.err(node, format!("{w} is not finite"))) }
            })
            .collect()
    }

    /// Three numbers from `value="x, y, z"` or from `x`, `y`, `z` attributes (each
    /// defaulting to `fill`).
    fn vec3(&self, node: Node, fill: f64) -> Result<DVec3> {
        if let Some(v) = self.attr(node, "value")? {
            let n = self.numbers(node, &v)?;
            return match n.as_slice() {
                [a] => Ok(DVec3::splat(*a)),
                [a, b, c] => Ok(DVec3::new(*a, *b, *c)),
                _ => Err(self.err(node, format!("expected one or three numbers, found {}", n.len()))),
            };
        }
        let mut out = DVec3::splat(fill);
        for (i, axis) in ["x", "y", "z"].iter().enumerate() {
            if let Some(v) = self.attr(node, axis)? {
                out[i] = self.number(node, &v)?;
            }
        }
        Ok(out)
    }

    fn number(&self, node: Node, text: &str) -> Result<f64> {
        match self.numbers(node, text)?.as_slice() {
            [v] => Ok(*v),
            n => Err(self.err(node, format!("expected one number, found {}", n.len()))),
        }
    }

    fn point_attr(&self, node: Node, name: &str) -> Result<DVec3> {
        let text = self.need(node, name)?;
        match self.numbers(node, &text)?.as_slice() {
            [a, b, c] => Ok(DVec3::new(*a, *b, *c)),
            n => Err(self.err(node, format!("{name}: expected three numbers, found {}", n.len()))),
        }
    }

    /// A `<transform>`: its children applied in order (each one left-multiplies).
    pub fn transform(&self, node: Node) -> Result<Mat4> {
        let mut m = DMat4::IDENTITY;
        for c in node.children().filter(Node::is_element) {
            // A step is its attributes; anything inside one would be ignored unseen.
            if let Some(inner) = c.children().find(Node::is_element) {
                return Err(self.err(
                    inner,
                    format!(
                        "<{}> inside a <{}> step: a step takes no elements",
                        inner.tag_name().name(),
                        c.tag_name().name()
                    ),
                ));
            }
            let step = match c.tag_name().name() {
                "translate" => DMat4::from_translation(self.vec3(c, 0.0)?),
                "scale" => DMat4::from_scale(self.vec3(c, 1.0)?),
                "rotate" => {
                    let axis = self.vec3(c, 0.0)?;
                    let angle = self.number(c, &self.need(c, "angle")?)?;
                    if axis.length_squared() == 0.0 {
                        return Err(self.err(c, "rotation axis is zero"));
                    }
                    DMat4::from_axis_angle(axis.normalize(), angle.to_radians())
                }
                "matrix" => {
                    let v = self.numbers(c, &self.need(c, "value")?)?;
                    match v.len() {
                        // Row-major in the file; glam is column-major.
                        16 => DMat4::from_cols_array(&v.try_into().unwrap()).transpose(),
                        9 => {
                            let r = |i: usize| [v[3 * i], v[3 * i + 1], v[3 * i + 2], 0.0];
                            let rows = [r(0), r(1), r(2), [0.0, 0.0, 0.0, 1.0]];
                            DMat4::from_cols_array_2d(&rows).transpose()
                        }
                        n => return Err(self.err(c, format!("a matrix has 9 or 16 numbers, found {n}"))),
                    }
                }
                "lookat" => {
                    let origin = self.point_attr(c, "origin")?;
                    let target = self.point_attr(c, "target")?;
                    let up = match self.attr(c, "up")? {
                        Some(_) => self.point_attr(c, "up")?,
                        None => DVec3::Y,
                    };
                    let dir = (target - origin).normalize_or_zero();
                    let left = up.cross(dir).normalize_or_zero();
                    if dir == DVec3::ZERO || left == DVec3::ZERO {
                        return Err(self.err(c, "origin equals target, or up is parallel to the view direction"));
                    }
                    let new_up = dir.cross(left);
                    DMat4::from_cols(left.extend(0.0), new_up.extend(0.0), dir.extend(0.0), origin.extend(1.0))
                }
                other => return Err(self.err(c, format!("unsupported transform step <{other}>"))),
            };
            m = step * m;
        }
        let m = m.as_mat4();
        if !m.is_finite() {
            return Err(self.err(node, "transform is not finite"));
        }
        Ok(m)
    }

    /// A property element's value.
    pub fn value(&self, node: Node) -> Result<Value> {
        let tag = node.tag_name().name();
        Ok(match tag {
            "float" | "integer" => Value::Number(self.number(node, &self.need(node, "value")?)?),
            "boolean" => match self.need(node, "value")?.as_str() {
                "true" => Value::Bool(true),
                "false" => Value::Bool(false),
                v => return Err(self.err(node, format!("'{v}' is not true or false"))),
            },
            "string" => Value::Text(self.need(node, "value")?),
            "rgb" | "spectrum" => {
                let text = self.need(node, "value")?;
                if tag == "spectrum" && text.contains(':') {
                    return Err(self.err(node, "sampled spectra (wavelength:value) are not supported; give one value"));
                }
                match self.numbers(node, &text)?.as_slice() {
                    [v] => Value::Color(Vec3::splat(*v as f32)),
                    [r, g, b] if tag == "rgb" => Value::Color(Vec3::new(*r as f32, *g as f32, *b as f32)),
                    n => return Err(self.err(node, format!("expected 1 or 3 numbers, found {}", n.len()))),
                }
            }
            "point" | "vector" => Value::Point(self.vec3(node, 0.0)?.as_vec3()),
            "transform" => Value::Transform(self.transform(node)?),
            _ => return Err(self.err(node, "not a property")),
        })
    }
}

/// `<tag type="..." id="...">`, for messages.
pub(crate) fn describe(node: Node) -> String {
    let mut s = format!("<{}", node.tag_name().name());
    for a in ["type", "name", "id"] {
        if let Some(v) = node.attribute(a) {
            s.push_str(&format!(" {a}=\"{v}\""));
        }
    }
    s.push('>');
    s
}

/// Tags that are properties (as opposed to nested plugins or references).
pub(crate) fn is_property(node: Node) -> bool {
    matches!(
        node.tag_name().name(),
        "float" | "integer" | "boolean" | "string" | "rgb" | "spectrum" | "point" | "vector" | "transform"
    )
}

/// A plugin's properties by name; reading one marks it used. [`Props::finish`] turns
/// any property left unread into an error, as Mitsuba itself does.
pub(crate) struct Props<'d, 'a, 'input> {
    doc: &'d Doc<'a>,
    node: Node<'a, 'input>,
    values: Vec<(String, Value, Node<'a, 'input>, bool)>,
}

impl<'d, 'a, 'input> Props<'d, 'a, 'input> {
    /// Reads every property child of `node`.
    pub fn of(doc: &'d Doc<'a>, node: Node<'a, 'input>) -> Result<Self> {
        let mut values: Vec<(String, Value, Node, bool)> = Vec::new();
        for c in node.children().filter(|c| c.is_element() && is_property(*c)) {
            let name = doc.need(c, "name")?;
            if values.iter().any(|(n, ..)| *n == name) {
                return Err(doc.err(c, format!("property '{name}' given twice")));
            }
            values.push((name, doc.value(c)?, c, false));
        }
        Ok(Props { doc, node, values })
    }

    fn take(&mut self, name: &str) -> Option<(Value, Node<'a, 'input>)> {
        let entry = self.values.iter_mut().find(|(n, ..)| n == name)?;
        entry.3 = true;
        Some((entry.1.clone(), entry.2))
    }

    /// A property of one type: `pick` takes the value it accepts, anything else is an
    /// error saying what was `expected`.
    fn typed<T>(&mut self, name: &str, expected: &str, pick: impl Fn(Value) -> Option<T>) -> Result<Option<T>> {
        match self.take(name) {
            None => Ok(None),
            Some((v, n)) => pick(v).map(Some).ok_or_else(|| self.doc.err(n, format!("expected {expected}"))),
        }
    }

    /// A number property.
    pub fn number(&mut self, name: &str) -> Result<Option<f64>> {
        self.typed(name, "a number (<float> or <integer>)", |v| if let Value::Number(x) = v { Some(x) } else { None })
    }

    /// A number property with a default.
    pub fn number_or(&mut self, name: &str, default: f64) -> Result<f64> {
        Ok(self.number(name)?.unwrap_or(default))
    }

    /// A boolean property with a default.
    pub fn bool_or(&mut self, name: &str, default: bool) -> Result<bool> {
        let b = self.typed(name, "a <boolean>", |v| if let Value::Bool(x) = v { Some(x) } else { None })?;
        Ok(b.unwrap_or(default))
    }

    /// A property given as a number or by name (`int_ior`: `<float value="1.5"/>` or
    /// `<string value="bk7"/>`): `Ok(number)` or `Err(name)`.
    pub fn number_or_name(&mut self, name: &str) -> Result<Option<std::result::Result<f64, String>>> {
        self.typed(name, "a number or a <string> name", |v| match v {
            Value::Number(x) => Some(Ok(x)),
            Value::Text(s) => Some(Err(s)),
            _ => None,
        })
    }

    /// A string property.
    pub fn text(&mut self, name: &str) -> Result<Option<String>> {
        self.typed(name, "a <string>", |v| if let Value::Text(x) = v { Some(x) } else { None })
    }

    /// A colour (`rgb`, single-valued `spectrum`, or a number as a grey).
    pub fn color_or(&mut self, name: &str, default: Vec3) -> Result<Vec3> {
        if let Some(tex) = self
            .node
            .children()
            .find(|c| c.is_element() && c.tag_name().name() == "texture" && c.attribute("name") == Some(name))
        {
            return Err(self.doc.err(tex, "textures are not supported; give an <rgb> value"));
        }
        let colour = self.typed(name, "a colour (<rgb> or <spectrum>)", |v| match v {
            Value::Color(c) => Some(c),
            Value::Number(x) => Some(Vec3::splat(x as f32)),
            _ => None,
        })?;
        Ok(colour.unwrap_or(default))
    }

    /// A point property.
    pub fn point(&mut self, name: &str) -> Result<Option<Vec3>> {
        self.typed(name, "a <point>", |v| if let Value::Point(x) = v { Some(x) } else { None })
    }

    /// The `to_world` transform (identity when absent).
    pub fn world_transform(&mut self) -> Result<Mat4> {
        let m =
            self.typed("to_world", "a <transform>", |v| if let Value::Transform(x) = v { Some(x) } else { None })?;
        Ok(m.unwrap_or(Mat4::IDENTITY))
    }

    /// Marks properties that are accepted and have no effect here.
    pub fn ignore(&mut self, names: &[&str]) {
        for n in names {
            self.take(n);
        }
    }

    /// Errors on the first property nothing read.
    pub fn finish(self) -> Result<()> {
        match self.values.iter().find(|v| !v.3) {
            None => Ok(()),
            Some((name, _, node, _)) => Err(self.doc.err(
                *node,
                format!("property '{name}' is not supported by {} (see docs/scene-format.md)", describe(self.node)),
            )),
        }
    }
}

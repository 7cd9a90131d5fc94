//! Mitsuba 3 scene XML → the project's scene document
//! ([`SceneDoc`](super::format::SceneDoc)), which then goes through the same
//! validation and construction as JSON scenes, so an XML scene and its JSON
//! twin give identical [`Scene`]s. `docs/scene-format.md` ("Mitsuba 3 XML")
//! lists the supported subset and the mappings.
//!
//! Every error names the element (`<shape type="cube" id="box">`), the
//! attribute or property and the line; with [`MitsubaOptions::lenient`]
//! unsupported features are approximated and reported as [`Warning`]s.

mod bsdf;
mod emitter;
mod integrator;
mod parse;
mod props;
mod sensor;
mod shape;
mod texture;
mod transform;
mod upgrade;

#[cfg(test)]
mod tests;

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use super::Scene;
use super::bitmap::Bitmaps;
use super::budget::{Budget, LoadLimits};
use super::error::SceneError;
use super::files::Files;
use super::format::{CameraDoc, EnvironmentDoc, MaterialDoc, SceneDoc, ShapeDoc};
use super::loader;

pub use parse::MAX_DEPTH;
use parse::{Element, quote};

/// How to treat what the project's scene model cannot represent.
#[derive(Clone, Debug, Default)]
pub struct MitsubaOptions {
    /// false (default): anything unsupported is an error. true: it is
    /// approximated as documented and listed in the returned warnings.
    pub lenient: bool,
    /// Values for `$name` parameters; they override the file's `<default>`s
    /// (like keyword arguments to Mitsuba's `load_file`).
    pub parameters: BTreeMap<String, String>,
}

/// Something approximated while reading the XML.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    /// 1-based line of the element concerned.
    pub line: u32,
    /// The element, e.g. `<bsdf type="dielectric" id="glass">`.
    pub element: String,
    pub message: String,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "line {}: {}: {}", self.line, self.element, self.message)
    }
}

/// Most [`Warning`]s kept per document. A lenient document of a few hundred
/// kilobytes can hold tens of thousands of unsupported elements; their
/// messages would cost far more memory (and log volume) than they are worth.
/// [`Warnings::total`] still counts every one.
pub const MAX_WARNINGS: usize = 100;

/// The approximations made while reading a document: the first
/// [`MAX_WARNINGS`] in document order (the slice this dereferences to) and
/// the exact count of all of them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Warnings {
    kept: Vec<Warning>,
    total: usize,
}

impl Warnings {
    /// Records `warning`; only the first [`MAX_WARNINGS`] are kept.
    fn push(&mut self, warning: Warning) {
        self.total += 1;
        if self.kept.len() < MAX_WARNINGS {
            self.kept.push(warning);
        }
    }

    /// Number of warnings, including those not kept.
    pub fn total(&self) -> usize {
        self.total
    }
}

impl std::ops::Deref for Warnings {
    type Target = [Warning];

    /// The kept warnings (at most [`MAX_WARNINGS`]).
    fn deref(&self) -> &[Warning] {
        &self.kept
    }
}

/// A located problem in the XML; becomes [`SceneError::Syntax`].
#[derive(Debug)]
pub(crate) struct XmlError {
    pub line: u32,
    pub column: u32,
    /// Element label plus attribute or property name.
    pub field: String,
    pub message: String,
    /// A typed error of a referenced file (missing, broken, outside the
    /// scenes directory) that keeps its kind.
    pub source: Option<Box<SceneError>>,
}

impl XmlError {
    fn into_scene_error(self, file: &str) -> SceneError {
        if let Some(source) = self.source {
            let origin = Origin {
                line: self.line,
                column: self.column,
                label: self.field,
            };
            let field = source.field().unwrap_or_default().to_string();
            return locate(*source, file, &[(field, origin)]);
        }
        SceneError::Syntax {
            file: file.to_string(),
            line: self.line as usize,
            column: self.column as usize,
            field: self.field,
            message: self.message,
        }
    }
}

/// Problems named in one error, at most.
const MAX_PROBLEMS_NAMED: usize = 20;

/// The first of a strict document's problems (located, naming its field),
/// its message followed by the others' (line, field and message each), or
/// `None` when there are none.
fn every_problem(problems: Vec<XmlError>) -> Option<XmlError> {
    let mut problems = problems.into_iter();
    let mut first = problems.next()?;
    let others: Vec<XmlError> = problems.collect();
    if !others.is_empty() {
        let listed: Vec<String> = others
            .iter()
            .take(MAX_PROBLEMS_NAMED)
            .map(|p| format!("line {}: {}: {}", p.line, p.field, p.message))
            .collect();
        let unlisted = others.len() - listed.len();
        first.message = format!(
            "{}; and {} more: {}{}",
            first.message,
            others.len(),
            listed.join("; "),
            if unlisted > 0 {
                format!("; ({unlisted} not listed)")
            } else {
                String::new()
            }
        );
    }
    Some(first)
}

/// Where a part of the generated document came from, so that errors found
/// by the shared loader (e.g. `shapes[2].to_world[1].scale[0]`) point back
/// to the XML line.
#[derive(Clone)]
struct Origin {
    line: u32,
    column: u32,
    label: String,
}

impl Origin {
    fn of(e: &Element) -> Self {
        Origin {
            line: e.line,
            column: e.column,
            label: e.label(),
        }
    }
}

/// Conversion state: the document being built and the XML facts needed to
/// build it.
pub(crate) struct Ctx<'a> {
    ids: HashMap<String, &'a Element>,
    lenient: bool,
    /// The images the translation reads (a texture's mean where a constant
    /// is wanted), each once, shared with the scene's build after it.
    bitmaps: &'a Bitmaps<'a>,
    warnings: Warnings,
    /// Unsupported features of a strict document, reported together once
    /// it has been read through.
    problems: Vec<XmlError>,
    materials: Vec<MaterialDoc>,
    /// Element (by position) → the material id it became.
    material_of: HashMap<(u32, u32), String>,
    shapes: Vec<ShapeDoc>,
    lights: Vec<serde_json::Map<String, serde_json::Value>>,
    environment: Option<EnvironmentDoc>,
    camera: Option<CameraDoc>,
    integrator: integrator::IntegratorSettings,
    /// Document field path → XML element, most specific last.
    origins: Vec<(String, Origin)>,
    /// Elements whose references are being followed (cycle detection).
    resolving: Vec<(u32, u32)>,
}

impl<'a> Ctx<'a> {
    /// Empty conversion state for a document whose elements with an `id` are `ids`.
    fn new(
        ids: HashMap<String, &'a Element>,
        options: &MitsubaOptions,
        bitmaps: &'a Bitmaps<'a>,
    ) -> Self {
        Ctx {
            ids,
            lenient: options.lenient,
            bitmaps,
            warnings: Warnings::default(),
            problems: Vec::new(),
            materials: Vec::new(),
            material_of: HashMap::new(),
            shapes: Vec::new(),
            lights: Vec::new(),
            environment: None,
            camera: None,
            integrator: Default::default(),
            origins: Vec::new(),
            resolving: Vec::new(),
        }
    }

    /// Participating media (`<medium>`, in a shape, a sensor or the
    /// scene) are not in the scene model: each is refused by name
    /// (lenient: left out, the space it fills rendered as vacuum).
    fn media(&mut self, media: &[&Element]) -> Result<(), XmlError> {
        for medium in media {
            let kind = medium.attr("type").unwrap_or("");
            self.unsupported(
                medium,
                "type",
                &format!(
                    "participating media are not supported (<medium type={}>)",
                    quote(kind)
                ),
                "leaving the medium out: vacuum",
            )?;
        }
        Ok(())
    }

    /// An unsupported feature: with `lenient` a warning saying what is done
    /// instead (`fallback`), else a problem that fails the document once it
    /// has been read through, so that every such problem is named at once.
    fn unsupported(
        &mut self,
        el: &Element,
        attribute: &str,
        what: &str,
        fallback: &str,
    ) -> Result<(), XmlError> {
        if self.lenient {
            self.warn(el, format!("{what}; {fallback}"));
        } else {
            self.problems.push(el.error(
                attribute,
                format!("{what} (pass lenient to approximate: {fallback})"),
            ));
        }
        Ok(())
    }

    fn warn(&mut self, el: &Element, message: impl Into<String>) {
        self.warnings.push(Warning {
            line: el.line,
            element: el.label(),
            message: message.into(),
        });
    }

    fn origin(&mut self, field: impl Into<String>, el: &Element) {
        self.origins.push((field.into(), Origin::of(el)));
    }

    /// Follows `<ref id="..."/>` to the element it names (other elements are
    /// returned as they are). Errors on unknown ids.
    fn deref(&self, el: &'a Element) -> Result<&'a Element, XmlError> {
        if el.tag != "ref" {
            return Ok(el);
        }
        let id = el
            .attr("id")
            .ok_or_else(|| el.error("id", "<ref> needs an `id`"))?;
        self.ids
            .get(id)
            .copied()
            .ok_or_else(|| el.error("id", format!("no element has id {}", quote(id))))
    }

    /// Marks `el` as being expanded; a second entry before [`Ctx::leave`] is
    /// a reference cycle.
    fn enter(&mut self, el: &Element) -> Result<(), XmlError> {
        if self.resolving.contains(&el.key()) {
            return Err(el.error("", "reference cycle: this element refers back to itself"));
        }
        // Chains of references recurse like nesting does.
        if self.resolving.len() >= MAX_DEPTH {
            return Err(el.error(
                "",
                format!("references and nesting chained deeper than {MAX_DEPTH} levels"),
            ));
        }
        self.resolving.push(el.key());
        Ok(())
    }

    fn leave(&mut self) {
        self.resolving.pop();
    }

    /// `Err` once the load is cancelled, located at `el`.
    fn check_cancel(&self, el: &Element) -> Result<(), XmlError> {
        self.bitmaps.budget().check_cancel().map_err(|e| XmlError {
            source: Some(Box::new(e)),
            ..el.error("", "")
        })
    }
}

/// Parses Mitsuba XML `text` (named `file` in messages) and builds the scene
/// within `limits`. Relative file names resolve against `base_dir` and must
/// stay inside `scenes_root`; messages name them relative to it.
pub(crate) fn from_str(
    text: &str,
    file: &str,
    base_dir: &Path,
    scenes_root: &Path,
    options: &MitsubaOptions,
    limits: &LoadLimits,
) -> Result<(Scene, Warnings), SceneError> {
    let files = Files::new(base_dir, scenes_root)?;
    translate_and_build(text, file, &files, options, limits).map_err(|e| files.relative(e))
}

fn translate_and_build(
    text: &str,
    file: &str,
    files: &Files,
    options: &MitsubaOptions,
    limits: &LoadLimits,
) -> Result<(Scene, Warnings), SceneError> {
    let budget = Budget::new(limits);
    let bitmaps = Bitmaps::new(files, &budget);
    let mut scene_el =
        parse::parse(text, &options.parameters).map_err(|e| e.into_scene_error(file))?;
    let version = scene_el.attr("version").and_then(upgrade::parse_version);
    let upgraded = version.map_or_else(Vec::new, |v| upgrade::upgrade(&mut scene_el, v));
    let ids = parse::index_ids(&scene_el).map_err(|e| e.into_scene_error(file))?;
    budget.check_cancel()?;
    let mut ctx = Ctx::new(ids, options, &bitmaps);
    for change in upgraded {
        ctx.warn(&scene_el, change);
    }
    let converted = convert_scene(&mut ctx, &scene_el);
    // A strict document's unsupported features come first: an error met
    // afterwards may be one of their stand-ins failing.
    if let Some(first) = every_problem(std::mem::take(&mut ctx.problems)) {
        return Err(first.into_scene_error(file));
    }
    let doc = converted.map_err(|e| e.into_scene_error(file))?;
    let Ctx {
        origins, warnings, ..
    } = ctx;
    let scene = loader::build(doc, files, &bitmaps).map_err(|e| locate(e, file, &origins))?;
    Ok((scene, warnings))
}

/// Reads and converts a `.xml` scene file within `limits`; the scene is
/// named after the file.
pub(crate) fn load(
    path: &Path,
    scenes_root: &Path,
    options: &MitsubaOptions,
    limits: &LoadLimits,
) -> Result<(Scene, Warnings), SceneError> {
    let text = loader::read_scene_file(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let (mut scene, warnings) = from_str(
        &text,
        &path.display().to_string(),
        base,
        scenes_root,
        options,
        limits,
    )?;
    loader::name_from_file(&mut scene, path);
    Ok((scene, warnings))
}

/// Supported `<scene version>`: Mitsuba 2 and 3 share the plugin names and
/// conventions used here; Mitsuba 0.x documents were upgraded to them
/// (`upgrade`).
fn check_version(ctx: &mut Ctx, scene: &Element) -> Result<(), XmlError> {
    let version = scene
        .attr("version")
        .ok_or_else(|| scene.error("version", "missing `version` (e.g. \"3.0.0\")"))?;
    match upgrade::parse_version(version) {
        Some((0..=3, _, _)) => Ok(()),
        _ => ctx.unsupported(
            scene,
            "version",
            &format!(
                "version {} is not a Mitsuba 0.x, 2 or 3 scene",
                quote(version)
            ),
            "reading it with Mitsuba 3 conventions",
        ),
    }
}

/// Reads top-level BSDF `el`, which no `<ref>` names: it changes no
/// picture, so what fails in it (a volume texture, a missing file) does
/// not fail the scene but leaves it out, with a warning naming it.
fn unused_bsdf<'a>(ctx: &mut Ctx<'a>, el: &'a Element, id: &str) {
    let (materials, problems) = (ctx.materials.len(), ctx.problems.len());
    let failure = match bsdf::material(ctx, el) {
        Err(e) => Some(e.message),
        Ok(_) => ctx.problems.get(problems).map(|e| e.message.clone()),
    };
    if let Some(why) = failure {
        ctx.problems.truncate(problems);
        ctx.materials.truncate(materials);
        let kept: std::collections::HashSet<&str> =
            ctx.materials.iter().map(|m| m.id.as_str()).collect();
        ctx.material_of.retain(|_, m| kept.contains(m.as_str()));
        ctx.warn(
            el,
            format!("BSDF {id:?} is used by no shape and left out, as it cannot be read: {why}"),
        );
    }
}

/// The ids that some `<ref>` under `el` names.
fn referenced_ids<'a>(el: &'a Element, out: &mut std::collections::HashSet<&'a str>) {
    for c in &el.children {
        if c.tag == "ref"
            && let Some(id) = c.attr("id")
        {
            out.insert(id);
        }
        referenced_ids(c, out);
    }
}

fn convert_scene<'a>(ctx: &mut Ctx<'a>, scene: &'a Element) -> Result<SceneDoc, XmlError> {
    check_version(ctx, scene)?;
    let mut referenced = std::collections::HashSet::new();
    referenced_ids(scene, &mut referenced);
    for el in &scene.children {
        ctx.check_cancel(el)?;
        match el.tag.as_str() {
            // Already applied while parsing.
            "default" => {}
            "integrator" => ctx.integrator = integrator::settings(ctx, el)?,
            "bsdf" => match el.attr("id") {
                Some(id) if !referenced.contains(id) => unused_bsdf(ctx, el, id),
                _ => {
                    bsdf::material(ctx, el)?;
                }
            },
            // Declarations used through <ref>; read where referenced.
            "texture" | "spectrum" | "rgb" | "float" => {}
            "shape" => shape::add(ctx, el, &transform::Ops::default())?,
            "emitter" => emitter::add(ctx, el)?,
            "sensor" => {
                if ctx.camera.is_some() {
                    ctx.unsupported(el, "", "more than one <sensor>", "using the first")?;
                } else {
                    ctx.camera = Some(sensor::camera(ctx, el)?);
                }
            }
            "medium" => ctx.media(&[el])?,
            _ => ctx.unsupported(
                el,
                "",
                &format!("<{}> is not supported at the top level of a scene", el.tag),
                "ignoring it",
            )?,
        }
    }
    let camera = match ctx.camera.take() {
        Some(c) => c,
        // A scene of meters needs no camera for what it measures; its
        // images get Mitsuba's default one.
        None if ctx.shapes.iter().any(|s| s.sensor.is_some()) => sensor::default_camera(),
        None => {
            ctx.unsupported(
                scene,
                "",
                "the scene has no <sensor>",
                "using Mitsuba's default perspective camera",
            )?;
            sensor::default_camera()
        }
    };
    Ok(SceneDoc {
        name: None,
        description: None,
        materials: std::mem::take(&mut ctx.materials),
        shapes: std::mem::take(&mut ctx.shapes),
        lights: std::mem::take(&mut ctx.lights),
        environment: ctx.environment.take(),
        camera,
        hide_emitters: ctx.integrator.hide_emitters,
        max_depth: ctx.integrator.max_depth,
    })
}

/// Maps an error of the shared loader (which names document fields) back to
/// the XML element the field came from.
fn locate(e: SceneError, file: &str, origins: &[(String, Origin)]) -> SceneError {
    let find = |field: &str| {
        origins
            .iter()
            .filter(|(prefix, _)| {
                field.strip_prefix(prefix.as_str()).is_some_and(|rest| {
                    rest.is_empty() || rest.starts_with('.') || rest.starts_with('[')
                })
            })
            .max_by_key(|(prefix, _)| prefix.len())
            .map(|(_, o)| o)
    };
    match e {
        SceneError::Invalid { field, message } => match find(&field) {
            Some(o) => SceneError::Syntax {
                file: file.to_string(),
                line: o.line as usize,
                column: o.column as usize,
                field: format!("{} ({field})", o.label),
                message,
            },
            None => SceneError::Invalid { field, message },
        },
        SceneError::PathEscape { field, path, root } => SceneError::PathEscape {
            field: relabel(&field, file, find(&field)),
            path,
            root,
        },
        SceneError::File {
            field,
            file: f,
            message,
        } => SceneError::File {
            field: relabel(&field, file, find(&field)),
            file: f,
            message,
        },
        SceneError::OverBudget {
            field,
            budget,
            message,
        } => SceneError::OverBudget {
            field: relabel(&field, file, find(&field)),
            budget,
            message,
        },
        other => other,
    }
}

fn relabel(field: &str, file: &str, origin: Option<&Origin>) -> String {
    match origin {
        Some(o) if o.label.ends_with(&format!(".{field}")) => {
            format!("{file}:{}: {}", o.line, o.label)
        }
        Some(o) => format!("{file}:{}: {} ({field})", o.line, o.label),
        None => field.to_string(),
    }
}

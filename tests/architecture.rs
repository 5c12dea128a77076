//! ARCHITECTURE.md's structural claims, checked against the source: no import circle
//! between modules, kiln-render's layers used only downwards, the "knows nothing of"
//! invariants, no source file over 1,000 lines and no production function over 120, no
//! code after a test module, and `kiln render` without the farm crate.
//!
//! The source is read as text: comments, strings and `#[cfg(test)]` modules are dropped,
//! and every `crate::` and `super::` path (in `use` lines and in code) is resolved to the
//! module that defines what it names. A dependency between two modules counts between the
//! two siblings that contain them (a file inside `shapes/` using `lights/` makes `shapes`
//! use `lights`); a module using its own parent or children is not a circle.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

/// A module: its crate and its path inside the crate (`["shapes", "quadric"]`).
type Module = (String, Vec<String>);

/// The workspace's crates, by folder under crates/.
const CRATES: [&str; 5] = ["scene", "render", "image", "farm", "cli"];

/// kiln-render's top-level modules from the bottom up, as ARCHITECTURE.md lists them: a
/// module uses only modules of lower layers.
const RENDER_LAYERS: &[&[&str]] = &[
    &[
        "math", "work", "rect", "motion", "sampling", "shared", "spectral", "simd",
    ],
    &[
        "textures", "phase", "filter", "sensor", "gbuffer", "features",
    ],
    &["shapes", "bsdfs", "sums"],
    &["nesting", "materials", "media", "lens", "adaptive", "film"],
    &["lights", "camera"],
    &["scene"],
    &["integrators"],
    &["tile"],
];

/// Modules that must never use others (crate, user, used), with ARCHITECTURE.md's reason.
const NEVER: &[(&str, &str, &str)] = &[
    // sampling/ and math.rs know nothing else in the crate.
    ("render", "sampling", "*"),
    ("render", "math", "*"),
    // spectral.rs and simd.rs know nothing else in the crate either.
    ("render", "spectral", "*"),
    ("render", "simd", "*"),
    // Textures know nothing of materials or lights.
    ("render", "textures", "materials"),
    ("render", "textures", "lights"),
    // Shapes know materials, lights and media only as indices.
    ("render", "shapes", "materials"),
    ("render", "shapes", "lights"),
    ("render", "shapes", "media"),
    // Materials and BSDFs know nothing of lights, media or scenes.
    ("render", "materials", "lights"),
    ("render", "materials", "media"),
    ("render", "materials", "scene"),
    ("render", "bsdfs", "lights"),
    ("render", "bsdfs", "media"),
    ("render", "bsdfs", "scene"),
    // Media know nothing of lights or scenes; lights nothing of integrators; the scene
    // nothing of integrators.
    ("render", "media", "lights"),
    ("render", "media", "scene"),
    ("render", "lights", "integrators"),
    ("render", "scene", "integrators"),
    // The scene crate's file readers know nothing of the parser's graphics state.
    ("scene", "files", "parser"),
    // The coordinator's HTTP layer never touches the store or the data directory.
    // The farm's https trust knows nothing else in the crate (client and coordinator share it).
    ("farm", "trust", "*"),
    ("farm", "coordinator::http", "coordinator::store"),
    ("farm", "coordinator::http", "coordinator::data_dir"),
    // The lease table knows nothing of jobs, the store or HTTP; a job (bookkeeping only)
    // never touches the database, the data directory or the leases.
    ("farm", "coordinator::leases", "coordinator::job"),
    ("farm", "coordinator::leases", "coordinator::store"),
    ("farm", "coordinator::leases", "coordinator::http"),
    ("farm", "coordinator::job", "coordinator::store::sqlite"),
    ("farm", "coordinator::job", "coordinator::data_dir"),
    ("farm", "coordinator::job", "coordinator::leases"),
];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every module of every crate, with its file.
fn modules() -> BTreeMap<Module, PathBuf> {
    let mut out = BTreeMap::new();
    for krate in CRATES {
        let src = repo().join("crates").join(krate).join("src");
        for file in rust_files(&src) {
            let rel = file.strip_prefix(&src).unwrap().with_extension("");
            let mut path: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(
                path.last().map(String::as_str),
                Some("mod" | "lib" | "main")
            ) {
                path.pop();
            }
            out.insert((krate.to_string(), path), file);
        }
    }
    out
}

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            files.extend(rust_files(&path));
        } else if path.extension().is_some_and(|e| e == "rs") {
            files.push(path);
        }
    }
    files.sort();
    files
}

/// Test code: a module that only builds for tests (tests.rs, proptests.rs, tests/).
fn is_test_file(file: &Path) -> bool {
    let name = file.file_name().unwrap().to_string_lossy();
    name == "tests.rs"
        || name == "proptests.rs"
        || file.components().any(|c| c.as_os_str() == "tests")
}

/// The source without comments and with every string and char literal emptied, line
/// breaks kept (so line numbers stay).
fn code_of(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    if b[i] == b'\n' {
                        out.push('\n');
                    }
                    i += 1;
                }
            }
        } else if (c == b'r' || c == b'b') && raw_string_start(b, i).is_some() {
            let (hashes, body) = raw_string_start(b, i).unwrap();
            i = body;
            out.push_str("\"\"");
            loop {
                if i >= b.len() {
                    break;
                }
                if b[i] == b'"'
                    && b[i + 1..]
                        .iter()
                        .take(hashes)
                        .filter(|&&h| h == b'#')
                        .count()
                        == hashes
                {
                    i += 1 + hashes;
                    break;
                }
                if b[i] == b'\n' {
                    out.push('\n');
                }
                i += 1;
            }
        } else if c == b'"' {
            out.push_str("\"\"");
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' {
                    i += 1;
                }
                if i < b.len() && b[i] == b'\n' {
                    out.push('\n');
                }
                i += 1;
            }
            i += 1;
        } else if c == b'\'' && char_literal_len(b, i).is_some() {
            out.push_str("' '");
            i += char_literal_len(b, i).unwrap();
        } else {
            out.push(c as char);
            i += 1;
        }
    }
    out
}

/// Where a raw string starting at `i` (`r"`, `r#"`, `br"`...) has its body, and its hashes.
fn raw_string_start(b: &[u8], i: usize) -> Option<(usize, usize)> {
    if i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_') {
        return None;
    }
    let mut j = i;
    if b[j] == b'b' {
        j += 1;
    }
    if b.get(j) != Some(&b'r') {
        return None;
    }
    j += 1;
    let mut hashes = 0;
    while b.get(j) == Some(&b'#') {
        hashes += 1;
        j += 1;
    }
    (b.get(j) == Some(&b'"')).then_some((hashes, j + 1))
}

/// The length of a char literal at `i` (`'a'`, `'\n'`, `'\u{1F600}'`), or None for a
/// lifetime.
fn char_literal_len(b: &[u8], i: usize) -> Option<usize> {
    match (b.get(i + 1), b.get(i + 2)) {
        (Some(b'\\'), _) => {
            let end = b[i + 2..].iter().position(|&c| c == b'\'')?;
            Some(end + 3)
        }
        (Some(_), Some(b'\'')) => Some(3),
        _ => {
            // A multi-byte character.
            let s = std::str::from_utf8(&b[i + 1..(i + 6).min(b.len())])
                .ok()
                .or_else(|| std::str::from_utf8(&b[i + 1..(i + 5).min(b.len())]).ok())?;
            let ch = s.chars().next()?;
            let n = ch.len_utf8();
            (b.get(i + 1 + n) == Some(&b'\'') && n > 1).then_some(n + 2)
        }
    }
}

/// The code outside `#[cfg(test)]` modules (their lines blanked).
fn without_test_modules(code: &str) -> String {
    let mut out = String::with_capacity(code.len());
    let mut rest = code;
    while let Some(at) = rest.find("#[cfg(test)]") {
        let after = &rest[at + "#[cfg(test)]".len()..];
        let trimmed = after.trim_start();
        let is_mod = trimmed.starts_with("mod ") || trimmed.starts_with("pub mod ");
        if !is_mod {
            out.push_str(&rest[..at + "#[cfg(test)]".len()]);
            rest = after;
            continue;
        }
        out.push_str(&rest[..at]);
        let body = &rest[at..];
        // `mod tests;` (a file of its own) or `mod tests { ... }`.
        let semi = body.find(';');
        let brace = body.find('{');
        let end = match (semi, brace) {
            (Some(s), Some(b)) if s < b => s + 1,
            (Some(s), None) => s + 1,
            (_, Some(b)) => matching_brace(body, b) + 1,
            (None, None) => body.len(),
        };
        out.extend(body[..end].chars().filter(|&c| c == '\n'));
        rest = &body[end..];
    }
    out.push_str(rest);
    out
}

/// The index of the brace closing the one at `open`.
fn matching_brace(code: &str, open: usize) -> usize {
    let mut depth = 0;
    for (i, c) in code[open..].char_indices() {
        match c {
            '{' => depth += 1,
            '}' => {
                depth -= 1;
                if depth == 0 {
                    return open + i;
                }
            }
            _ => {}
        }
    }
    code.len() - 1
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The names a module defines (types, functions, constants, statics, traits).
fn definitions(code: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    let words: Vec<&str> = code
        .split(|c: char| !is_ident(c))
        .filter(|w| !w.is_empty())
        .collect();
    for w in words.windows(2) {
        if matches!(
            w[0],
            "struct" | "enum" | "fn" | "trait" | "type" | "const" | "static" | "union"
        ) {
            names.insert(w[1].to_string());
        }
    }
    names
}

/// Every path the code names from `crate::` or `super::`: its root (`crate`, or `super`
/// repeated) and its segments, a `use` group expanded into one path per name.
fn paths(code: &str) -> Vec<(usize, Vec<String>)> {
    let mut out = Vec::new();
    let b = code.as_bytes();
    let mut i = 0;
    while i < b.len() {
        let starts = (code[i..].starts_with("crate::") || code[i..].starts_with("super::"))
            && (i == 0 || !is_ident(b[i - 1] as char));
        if !starts {
            i += 1;
            continue;
        }
        let mut supers = 0;
        let mut j = i;
        if code[j..].starts_with("crate::") {
            j += "crate::".len();
        } else {
            while code[j..].starts_with("super::") {
                supers += 1;
                j += "super::".len();
            }
        }
        let mut segments = Vec::new();
        loop {
            let start = j;
            while j < b.len() && is_ident(b[j] as char) {
                j += 1;
            }
            if j > start {
                segments.push(code[start..j].to_string());
            }
            if code[j..].starts_with("::") && b.get(j + 2).is_some_and(|&c| is_ident(c as char)) {
                j += 2;
                continue;
            }
            break;
        }
        if code[j..].starts_with("::{") {
            let close = matching_brace(code, j + 2);
            for item in code[j + 3..close].split(',') {
                let item = item.split(" as ").next().unwrap().trim();
                let item: Vec<String> = item
                    .split("::")
                    .map(|s| s.trim_matches(|c: char| !is_ident(c)).to_string())
                    .filter(|s| !s.is_empty() && s != "self")
                    .collect();
                let mut full = segments.clone();
                full.extend(item);
                out.push((supers, full));
            }
            j = close;
        }
        out.push((supers, segments));
        i = j.max(i + 1);
    }
    out
}

/// What each module uses: the modules that define what its paths name.
fn uses(all: &BTreeMap<Module, PathBuf>) -> BTreeMap<Module, BTreeSet<Module>> {
    let code: BTreeMap<&Module, String> = all
        .iter()
        .filter(|(_, f)| !is_test_file(f))
        .map(|(m, f)| {
            (
                m,
                without_test_modules(&code_of(&std::fs::read_to_string(f).unwrap())),
            )
        })
        .collect();
    let defs: HashMap<&Module, BTreeSet<String>> =
        code.iter().map(|(m, c)| (*m, definitions(c))).collect();
    let mut out: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for ((krate, here), text) in &code {
        for (supers, segments) in paths(text) {
            // `crate` is the root; each `super` the parent of the module before it.
            let mut base = if supers == 0 {
                Vec::new()
            } else {
                here.clone()
            };
            for _ in 0..supers {
                base.pop();
            }
            let target = resolve(all, &defs, krate, base, &segments);
            if target != *here {
                out.entry((krate.clone(), here.clone()))
                    .or_default()
                    .insert((krate.clone(), target));
            }
        }
    }
    out
}

/// The module a path from `base` names: the deepest module its segments walk through,
/// and, where the next segment is an item re-exported there, the one module inside it
/// that defines the item.
fn resolve(
    all: &BTreeMap<Module, PathBuf>,
    defs: &HashMap<&Module, BTreeSet<String>>,
    krate: &str,
    mut module: Vec<String>,
    segments: &[String],
) -> Vec<String> {
    let mut rest = segments.iter();
    let mut next = rest.next();
    while let Some(s) = next {
        let mut deeper = module.clone();
        deeper.push(s.clone());
        if !all.contains_key(&(krate.to_string(), deeper.clone())) {
            break;
        }
        module = deeper;
        next = rest.next();
    }
    let Some(item) = next else {
        return module;
    };
    let key = (krate.to_string(), module.clone());
    if defs.get(&key).is_some_and(|d| d.contains(item)) {
        return module;
    }
    let inside: Vec<&Module> = defs
        .iter()
        .filter(|(m, d)| m.0 == krate && m.1.starts_with(&module) && d.contains(item))
        .map(|(m, _)| *m)
        .collect();
    match inside.as_slice() {
        [one] => one.1.clone(),
        _ => module,
    }
}

/// The dependencies between siblings: for each module, which of its children use which
/// (a use from inside a child's subtree into another child's counts for those children).
fn sibling_uses(
    uses: &BTreeMap<Module, BTreeSet<Module>>,
) -> BTreeMap<Module, BTreeMap<String, BTreeSet<String>>> {
    let mut out: BTreeMap<Module, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for ((krate, from), targets) in uses {
        for (_, to) in targets {
            let common = from.iter().zip(to).take_while(|(a, b)| a == b).count();
            if common == from.len() || common == to.len() {
                continue;
            }
            out.entry((krate.clone(), from[..common].to_vec()))
                .or_default()
                .entry(from[common].clone())
                .or_default()
                .insert(to[common].clone());
        }
    }
    out
}

/// The strongly connected components of more than one node (Tarjan's algorithm).
fn circles(graph: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    struct Walk<'a> {
        graph: &'a BTreeMap<String, BTreeSet<String>>,
        index: HashMap<&'a str, usize>,
        low: HashMap<&'a str, usize>,
        stack: Vec<&'a str>,
        found: Vec<Vec<String>>,
    }
    impl<'a> Walk<'a> {
        fn visit(&mut self, v: &'a str) {
            let n = self.index.len();
            self.index.insert(v, n);
            self.low.insert(v, n);
            self.stack.push(v);
            for w in self.graph.get(v).into_iter().flatten() {
                if !self.index.contains_key(w.as_str()) {
                    self.visit(w);
                    let lw = self.low[w.as_str()];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(lw);
                } else if self.stack.contains(&w.as_str()) {
                    let iw = self.index[w.as_str()];
                    let lv = self.low.get_mut(v).unwrap();
                    *lv = (*lv).min(iw);
                }
            }
            if self.low[v] == self.index[v] {
                let mut component = Vec::new();
                while let Some(w) = self.stack.pop() {
                    component.push(w.to_string());
                    if w == v {
                        break;
                    }
                }
                if component.len() > 1 {
                    component.sort();
                    self.found.push(component);
                }
            }
        }
    }
    let mut walk = Walk {
        graph,
        index: HashMap::new(),
        low: HashMap::new(),
        stack: Vec::new(),
        found: Vec::new(),
    };
    let nodes: BTreeSet<&str> = graph
        .iter()
        .flat_map(|(k, v)| std::iter::once(k.as_str()).chain(v.iter().map(String::as_str)))
        .collect();
    for v in nodes {
        if !walk.index.contains_key(v) {
            walk.visit(v);
        }
    }
    walk.found
}

fn describe(krate: &str, module: &[String]) -> String {
    if module.is_empty() {
        format!("kiln-{krate}")
    } else {
        format!("kiln-{krate}::{}", module.join("::"))
    }
}

#[test]
fn no_module_imports_one_that_imports_it_back() {
    let all = modules();
    let siblings = sibling_uses(&uses(&all));
    let mut found = Vec::new();
    for ((krate, parent), graph) in &siblings {
        for circle in circles(graph) {
            found.push(format!(
                "in {}: {}",
                describe(krate, parent),
                circle.join(" <-> ")
            ));
        }
    }
    assert!(found.is_empty(), "import circles:\n{}", found.join("\n"));
    // The check sees dependencies: the renderer's top level has dozens.
    let render_top = &siblings[&("render".to_string(), Vec::new())];
    assert!(render_top.values().map(BTreeSet::len).sum::<usize>() > 40);
}

#[test]
fn the_renderer_uses_its_layers_only_downwards() {
    let all = modules();
    let layer_of = |m: &str| RENDER_LAYERS.iter().position(|l| l.contains(&m));
    let top: BTreeSet<&String> = all
        .keys()
        .filter(|(k, p)| k == "render" && p.len() == 1)
        .map(|(_, p)| &p[0])
        .collect();
    let unlisted: Vec<_> = top.iter().filter(|m| layer_of(m).is_none()).collect();
    assert!(
        unlisted.is_empty(),
        "modules of kiln-render in no layer (add them to ARCHITECTURE.md and RENDER_LAYERS): {unlisted:?}"
    );
    let siblings = sibling_uses(&uses(&all));
    let mut upward = Vec::new();
    for (from, to) in &siblings[&("render".to_string(), Vec::new())] {
        for t in to {
            if layer_of(t) >= layer_of(from) {
                upward.push(format!(
                    "{from} (layer {:?}) uses {t} (layer {:?})",
                    layer_of(from),
                    layer_of(t)
                ));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "kiln-render uses up or sideways:\n{}",
        upward.join("\n")
    );
}

#[test]
fn modules_know_nothing_of_what_the_architecture_says_they_do_not() {
    let all = modules();
    let uses = uses(&all);
    let within = |m: &[String], prefix: &str| {
        prefix == "*" || {
            let p: Vec<&str> = prefix.split("::").collect();
            m.len() >= p.len() && m.iter().zip(&p).all(|(a, b)| a == b)
        }
    };
    let mut broken = Vec::new();
    for &(krate, user, used) in NEVER {
        for ((k, from), targets) in &uses {
            if k != krate || !within(from, user) {
                continue;
            }
            for (_, to) in targets {
                let outside = !within(to, user);
                if outside && within(to, used) {
                    broken.push(format!(
                        "{} uses {}",
                        describe(krate, from),
                        describe(krate, to)
                    ));
                }
            }
        }
    }
    assert!(broken.is_empty(), "{}", broken.join("\n"));
}

#[test]
fn no_source_file_over_1000_lines_and_no_function_over_120() {
    let all = modules();
    let mut big = Vec::new();
    for file in all.values() {
        let text = std::fs::read_to_string(file).unwrap();
        let lines = text.lines().count();
        let rel = file.strip_prefix(repo()).unwrap().display().to_string();
        if lines > 1000 {
            big.push(format!("{rel}: {lines} lines"));
        }
        if is_test_file(file) {
            continue;
        }
        let code = without_test_modules(&code_of(&text));
        for (name, line, length) in functions(&code) {
            if length > 120 {
                big.push(format!("{rel}:{line}: fn {name} is {length} lines"));
            }
        }
    }
    assert!(big.is_empty(), "{}", big.join("\n"));
}

#[test]
fn no_code_follows_a_test_module() {
    let (mut after, mut seen) = (Vec::new(), 0);
    for file in modules().values() {
        let code = code_of(&std::fs::read_to_string(file).unwrap());
        let Some(at) = code.find("#[cfg(test)]\nmod tests {") else {
            continue;
        };
        seen += 1;
        let open = at + code[at..].find('{').unwrap();
        let rest = &code[matching_brace(&code, open) + 1..];
        if !rest.trim().is_empty() {
            after.push(file.strip_prefix(repo()).unwrap().display().to_string());
        }
    }
    assert!(
        seen > 30,
        "only {seen} test modules found: the search is wrong"
    );
    assert!(after.is_empty(), "code after the test module in {after:?}");
}

/// `kiln render` goes through kiln-scene, kiln-render and kiln-image, never the farm.
#[test]
fn kiln_render_needs_no_farm() {
    let file = repo().join("crates/cli/src/render.rs");
    let code = code_of(&std::fs::read_to_string(&file).unwrap());
    assert!(
        !code.contains("kiln_farm"),
        "{} uses kiln_farm",
        file.display()
    );
    assert!(code.contains("kiln_render") && code.contains("kiln_image"));
}

/// Every function with a body: its name, first line and length in lines.
fn functions(code: &str) -> Vec<(String, usize, usize)> {
    let mut out = Vec::new();
    let b = code.as_bytes();
    let mut i = 0;
    while let Some(at) = code[i..].find("fn ") {
        let start = i + at;
        i = start + 3;
        if start > 0 && is_ident(b[start - 1] as char) {
            continue;
        }
        let name: String = code[i..].chars().take_while(|&c| is_ident(c)).collect();
        if name.is_empty() {
            continue;
        }
        // The body is the first brace before any `;` (a declaration has none).
        let Some(open) = code[i..].find(['{', ';']).map(|k| i + k) else {
            break;
        };
        if b[open] == b';' {
            continue;
        }
        let close = matching_brace(code, open);
        let first = code[..start].matches('\n').count() + 1;
        let last = code[..close].matches('\n').count() + 1;
        out.push((name, first, last - first + 1));
    }
    out
}

/// The checks above can fail: a made-up circle, an upward use and a long function are
/// each found.
#[test]
fn the_architecture_checks_see_what_they_look_for() {
    let graph: BTreeMap<String, BTreeSet<String>> = [
        ("a".to_string(), BTreeSet::from(["b".to_string()])),
        ("b".to_string(), BTreeSet::from(["c".to_string()])),
        ("c".to_string(), BTreeSet::from(["a".to_string()])),
        ("d".to_string(), BTreeSet::from(["a".to_string()])),
    ]
    .into();
    assert_eq!(circles(&graph), [vec!["a", "b", "c"]]);
    let code = code_of(
        "use crate::x::{Y, z::W};\nfn f() {\n let s = \"}{\"; // }\n super::super::q::R::new();\n}\n#[cfg(test)]\nmod tests { fn g() { crate::t::T; } }\n",
    );
    let code = without_test_modules(&code);
    let found: Vec<_> = paths(&code).into_iter().collect();
    assert!(found.contains(&(0, vec!["x".into(), "Y".into()])));
    assert!(found.contains(&(0, vec!["x".into(), "z".into(), "W".into()])));
    assert!(found.contains(&(2, vec!["q".into(), "R".into(), "new".into()])));
    assert!(!found.iter().any(|(_, p)| p[0] == "t"), "{found:?}");
    assert_eq!(functions(&code), [("f".to_string(), 2, 4)]);
}

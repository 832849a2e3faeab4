//! The crate's source read as a module tree, for the house's layering guards: each module's library
//! code (comments, literals and test code blanked out), the paths it names, and which sibling
//! modules those paths reach.
//!
//! This is a reader of the crate's own conventions, not a Rust parser: it knows `mod` files and
//! folders, inline `mod name { … }`, `use` trees (groups, globs, `as`, `self`) and `crate::`,
//! `super::` and `self::` paths, and follows re-exports to the module that defines an item.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module's path from the crate root (empty for the root).
pub type ModulePath = Vec<String>;

/// Every `.rs` file below `dir`.
pub fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("the source folder is readable") {
        let path = entry.expect("a directory entry").path();
        if path.is_dir() {
            files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The library code of `path`, line for line: comments, the insides of string and char literals
/// and test code (a `tests.rs` file, any item under `#[cfg(test)]`) blanked, so that neither a doc
/// link nor a test counts as a dependency.
pub fn library_text(path: &Path) -> String {
    if path.file_name().is_some_and(|n| n == "tests.rs") {
        return String::new();
    }
    let text = std::fs::read_to_string(path).expect("source is readable");
    let mut code = blank_comments_and_literals(&text).into_bytes();
    blank_test_items(&mut code);
    String::from_utf8_lossy(&code).into_owned()
}

/// Replaces `code[from..to]` with spaces, keeping its line breaks.
fn blank(code: &mut [u8], from: usize, to: usize) {
    let to = to.min(code.len());
    for b in &mut code[from..to] {
        if *b != b'\n' {
            *b = b' ';
        }
    }
}

fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

/// `text` with comments and the insides of string and char literals replaced by spaces.
fn blank_comments_and_literals(text: &str) -> String {
    let c = text.as_bytes();
    let mut out = c.to_vec();
    let mut i = 0;
    while i < c.len() {
        let next = c.get(i + 1).copied();
        let after_ident = i > 0 && is_ident(c[i - 1]) && c[i - 1] != b'b';
        if c[i] == b'/' && next == Some(b'/') {
            let end = (i..c.len()).find(|&j| c[j] == b'\n').unwrap_or(c.len());
            blank(&mut out, i, end);
            i = end;
        } else if c[i] == b'/' && next == Some(b'*') {
            let (mut depth, mut j) = (0, i);
            while j < c.len() {
                if c[j..].starts_with(b"/*") {
                    (depth, j) = (depth + 1, j + 2);
                } else if c[j..].starts_with(b"*/") {
                    (depth, j) = (depth - 1, j + 2);
                    if depth == 0 {
                        break;
                    }
                } else {
                    j += 1;
                }
            }
            blank(&mut out, i, j);
            i = j;
        } else if c[i] == b'r' && !after_ident && matches!(next, Some(b'"' | b'#')) {
            let hashes = c[i + 1..].iter().take_while(|&&b| b == b'#').count();
            if c.get(i + 1 + hashes) != Some(&b'"') {
                i += 1;
                continue;
            }
            let close = [&b"\""[..], &vec![b'#'; hashes]].concat();
            let start = i + 2 + hashes;
            let end = (start..c.len())
                .find(|&j| c[j..].starts_with(&close))
                .unwrap_or(c.len());
            blank(&mut out, start, end);
            i = end + close.len();
        } else if c[i] == b'"' {
            let mut j = i + 1;
            while j < c.len() && c[j] != b'"' {
                j += if c[j] == b'\\' { 2 } else { 1 };
            }
            blank(&mut out, i + 1, j);
            i = j + 1;
        } else if c[i] == b'\'' && next == Some(b'\\') {
            let end = (i + 3..c.len()).find(|&j| c[j] == b'\'').unwrap_or(c.len());
            blank(&mut out, i + 1, end);
            i = end + 1;
        } else if c[i] == b'\'' && c.get(i + 2) == Some(&b'\'') {
            blank(&mut out, i + 1, i + 2);
            i += 3;
        } else {
            i += 1;
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The index of the bracket that closes the one at `open`.
fn matching(code: &[u8], open: usize) -> usize {
    let (o, c) = (
        code[open],
        match code[open] {
            b'(' => b')',
            b'[' => b']',
            _ => b'}',
        },
    );
    let mut depth = 0;
    for (j, &b) in code.iter().enumerate().skip(open) {
        if b == o {
            depth += 1;
        } else if b == c {
            depth -= 1;
            if depth == 0 {
                return j;
            }
        }
    }
    code.len()
}

/// Blanks every item under `#[cfg(test)]`: up to its `;`, or to the end of its block.
fn blank_test_items(code: &mut [u8]) {
    const KEY: &[u8] = b"#[cfg(test)]";
    let mut from = 0;
    while let Some(at) = (from..code.len()).find(|&i| code[i..].starts_with(KEY)) {
        let mut i = at + KEY.len();
        loop {
            while i < code.len() && code[i].is_ascii_whitespace() {
                i += 1;
            }
            if !code[i..].starts_with(b"#[") {
                break;
            }
            i = matching(code, i + 1) + 1;
        }
        let mut depth = 0i32;
        let mut end = code.len();
        for j in i..code.len() {
            match code[j] {
                b'(' | b'[' => depth += 1,
                b')' | b']' => depth -= 1,
                b';' if depth == 0 => {
                    end = j + 1;
                    break;
                }
                b'{' if depth == 0 => {
                    end = matching(code, j) + 1;
                    break;
                }
                _ => {}
            }
        }
        blank(code, at, end);
        from = end;
    }
}

/// The identifier starting at `i`, if any.
fn ident_at(code: &[u8], i: usize) -> &str {
    let end = (i..code.len())
        .find(|&j| !is_ident(code[j]))
        .unwrap_or(code.len());
    std::str::from_utf8(&code[i..end]).unwrap_or("")
}

fn skip_space(code: &[u8], mut i: usize) -> usize {
    while i < code.len() && code[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

/// Where the keyword `word` occurs in `code` as a whole word.
fn keyword_at(code: &[u8], word: &str) -> Vec<usize> {
    let w = word.as_bytes();
    (0..code.len())
        .filter(|&i| code[i..].starts_with(w))
        .filter(|&i| i == 0 || !is_ident(code[i - 1]))
        .filter(|&i| code.get(i + w.len()).is_none_or(|&b| !is_ident(b)))
        .collect()
}

/// One name a `use` brings in (or a glob), and where it is written.
#[derive(Debug, Clone)]
pub struct UseLeaf {
    pub path: Vec<String>,
    /// The name it binds; `None` for a glob (`path` is then the module globbed).
    pub binding: Option<String>,
    pub offset: usize,
}

/// The leaves of the use tree in `code[from..to]`, below `prefix`.
fn use_tree(code: &[u8], from: usize, to: usize, prefix: &[String], out: &mut Vec<UseLeaf>) {
    let mut i = skip_space(code, from);
    let start = i;
    let mut path = prefix.to_vec();
    loop {
        if i >= to {
            break;
        }
        if code[i] == b'{' {
            let close = matching(code, i).min(to);
            let (mut part, mut depth) = (i + 1, 0);
            for j in i + 1..=close {
                match code[j] {
                    b'{' => depth += 1,
                    b'}' if depth > 0 => depth -= 1,
                    b',' | b'}' if depth == 0 => {
                        use_tree(code, part, j, &path, out);
                        part = j + 1;
                    }
                    _ => {}
                }
            }
            return;
        }
        if code[i] == b'*' {
            out.push(UseLeaf {
                path,
                binding: None,
                offset: start,
            });
            return;
        }
        let name = ident_at(code, i);
        if name.is_empty() {
            break;
        }
        path.push(name.to_string());
        i = skip_space(code, i + name.len());
        if code[i..].starts_with(b"::") {
            i = skip_space(code, i + 2);
        } else {
            break;
        }
    }
    if path.len() == prefix.len() {
        return;
    }
    if path.last().is_some_and(|s| s == "self") {
        path.pop();
    }
    let mut binding = path.last().cloned();
    if i < to && code[i..to].starts_with(b"as") {
        binding = Some(ident_at(code, skip_space(code, i + 2)).to_string());
    }
    out.push(UseLeaf {
        path,
        binding,
        offset: start,
    });
}

/// One module's library code and what it names.
pub struct Module {
    pub file: PathBuf,
    pub text: String,
    /// Its `use` leaves (their bindings are names in this module).
    pub uses: Vec<UseLeaf>,
    /// Every path it names: the `use` leaves and the `crate::`, `super::`, `self::` paths written
    /// elsewhere, with their offsets in `text`.
    pub paths: Vec<(Vec<String>, usize)>,
    /// The items its own code defines (not through a `use`).
    defined: BTreeSet<String>,
    /// The modules it declares, with `mod name;` or `mod name { … }`.
    declared: BTreeSet<String>,
}

impl Module {
    fn new(file: PathBuf, text: String) -> Self {
        let code = text.as_bytes();
        let mut uses = Vec::new();
        let mut statements = Vec::new();
        for at in keyword_at(code, "use") {
            if code.get(at + 3).is_some_and(|b| b.is_ascii_whitespace()) {
                let end = (at..code.len())
                    .find(|&j| code[j] == b';')
                    .unwrap_or(code.len());
                use_tree(code, at + 3, end, &[], &mut uses);
                statements.push(at..end);
            }
        }
        let mut paths: Vec<_> = uses.iter().map(|u| (u.path.clone(), u.offset)).collect();
        for root in ["crate", "super", "self"] {
            for at in keyword_at(code, root) {
                let written_after = at > 0 && code[at - 1] == b':';
                if written_after || statements.iter().any(|s| s.contains(&at)) {
                    continue;
                }
                let (mut path, mut i) = (Vec::new(), at);
                loop {
                    let name = ident_at(code, i);
                    if name.is_empty() {
                        break;
                    }
                    path.push(name.to_string());
                    i += name.len();
                    if !code[i..].starts_with(b"::") {
                        break;
                    }
                    i += 2;
                }
                if path.len() > 1 {
                    paths.push((path, at));
                }
            }
        }
        let mut defined = BTreeSet::new();
        for kind in [
            "fn",
            "struct",
            "enum",
            "trait",
            "type",
            "const",
            "static",
            "union",
            "macro_rules",
        ] {
            for at in keyword_at(code, kind) {
                let i = skip_space(code, at + kind.len() + usize::from(kind == "macro_rules"));
                defined.insert(ident_at(code, i).to_string());
            }
        }
        let declared = keyword_at(code, "mod")
            .into_iter()
            .map(|at| ident_at(code, skip_space(code, at + 3)).to_string())
            .collect();
        Module {
            file,
            uses,
            paths,
            defined,
            declared,
            text,
        }
    }

    /// The 1-based line of `offset`.
    pub fn line(&self, offset: usize) -> usize {
        self.text.as_bytes()[..offset]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1
    }
}

/// Splits the inline `mod name { … }` blocks out of `text` (module `path`), each as a module of its
/// own with the rest of the file blanked.
fn inline_modules(path: ModulePath, text: String, out: &mut Vec<(ModulePath, String)>) {
    let mut outer = text.into_bytes();
    let mut from = 0;
    while let Some((name, open)) = keyword_at(&outer, "mod")
        .into_iter()
        .filter(|&at| at >= from)
        .find_map(|at| {
            let i = skip_space(&outer, at + 3);
            let name = ident_at(&outer, i).to_string();
            let open = skip_space(&outer, i + name.len());
            (!name.is_empty() && outer.get(open) == Some(&b'{')).then_some((name, open))
        })
    {
        let close = matching(&outer, open);
        let mut inner = outer.clone();
        blank(&mut inner, 0, open + 1);
        blank(&mut inner, close, outer.len());
        blank(&mut outer, open + 1, close);
        let child = [path.clone(), vec![name]].concat();
        inline_modules(child, String::from_utf8_lossy(&inner).into_owned(), out);
        from = close;
    }
    out.push((path, String::from_utf8_lossy(&outer).into_owned()));
}

/// The crate's library modules, each declared by its parent.
pub struct Crate {
    pub modules: BTreeMap<ModulePath, Module>,
}

/// A sibling module's use of another, and where one such use is written (`file:line`).
pub type SiblingUses = BTreeMap<(ModulePath, ModulePath), String>;

impl Crate {
    /// Reads `src/` below `root`.
    pub fn read(root: &Path) -> Self {
        let src = root.join("src");
        let mut all = Vec::new();
        files(&src, &mut all);
        let mut found = Vec::new();
        for file in all {
            let relative = file.strip_prefix(root).unwrap().to_path_buf();
            let mut path: ModulePath = file
                .strip_prefix(&src)
                .unwrap()
                .iter()
                .map(|p| p.to_string_lossy().trim_end_matches(".rs").to_string())
                .collect();
            if path == ["lib"] || path.last().is_some_and(|p| p == "mod") {
                path.pop();
            }
            // A `tests` module folder holds test code.
            if path.iter().any(|p| p == "tests") {
                continue;
            }
            let mut pieces = Vec::new();
            inline_modules(path, library_text(&file), &mut pieces);
            found.extend(pieces.into_iter().map(|(p, t)| (p, relative.clone(), t)));
        }
        found.sort_by(|a, b| a.0.cmp(&b.0));
        let mut modules: BTreeMap<ModulePath, Module> = BTreeMap::new();
        for (path, file, text) in found {
            let declared = match path.split_last() {
                None => true,
                Some((name, parent)) => modules
                    .get(parent)
                    .is_some_and(|p| p.declared.contains(name)),
            };
            if declared {
                modules.insert(path, Module::new(file, text));
            }
        }
        Crate { modules }
    }

    /// The children of `parent`.
    pub fn children(&self, parent: &[String]) -> Vec<String> {
        self.modules
            .keys()
            .filter(|p| p.len() == parent.len() + 1 && p.starts_with(parent))
            .map(|p| p[parent.len()].clone())
            .collect()
    }

    /// The module `path` (written in module `from`) reaches, and whether the whole path names a
    /// module (rather than an item in it); `None` for other crates' paths.
    pub fn resolve(
        &self,
        from: &[String],
        path: &[String],
        depth: u32,
    ) -> Option<(ModulePath, bool)> {
        let mut at = from.to_vec();
        let mut rest = path;
        match rest.first().map(String::as_str) {
            Some("crate") => {
                at.clear();
                rest = &rest[1..];
            }
            Some("self") => rest = &rest[1..],
            Some("super") => {
                while rest.first().is_some_and(|s| s == "super") {
                    at.pop()?;
                    rest = &rest[1..];
                }
            }
            _ => {
                let (found, is_module) = self.lookup(&at, rest.first()?, depth)?;
                if !is_module {
                    return Some((found, false));
                }
                (at, rest) = (found, &rest[1..]);
            }
        }
        for name in rest {
            match self.lookup(&at, name, depth) {
                Some((found, true)) => at = found,
                Some((found, false)) => return Some((found, false)),
                None => return Some((at, false)),
            }
        }
        Some((at, true))
    }

    /// What `name` means inside module `module`: a child module, a `use` binding (followed), an
    /// item it defines, or one a glob brings in.
    fn lookup(&self, module: &[String], name: &str, depth: u32) -> Option<(ModulePath, bool)> {
        let m = self.modules.get(module)?;
        if depth > 16 {
            return None;
        }
        let child = [module, &[name.to_string()]].concat();
        if self.modules.contains_key(&child) {
            return Some((child, true));
        }
        let bound = m.uses.iter().find(|u| u.binding.as_deref() == Some(name));
        if let Some(leaf) = bound {
            return self.resolve(module, &leaf.path, depth + 1);
        }
        if m.defined.contains(name) {
            return Some((module.to_vec(), false));
        }
        // Globs of this crate's modules only (another crate's cannot lead back into this one).
        let local = |path: &[String]| {
            path.first().is_some_and(|first| {
                ["crate", "super", "self"].contains(&first.as_str())
                    || self
                        .modules
                        .contains_key(&[module, std::slice::from_ref(first)].concat())
            })
        };
        let mut globs = m
            .uses
            .iter()
            .filter(|u| u.binding.is_none() && local(&u.path));
        globs.find_map(|glob| match self.resolve(module, &glob.path, depth + 1)? {
            (q, true) if q != module => self.lookup(&q, name, depth + 1),
            _ => None,
        })
    }

    /// Every use of one sibling module by another, at every level of the tree: module `a` uses
    /// sibling `b` when code in `a`'s subtree names something defined in `b`'s.
    pub fn sibling_uses(&self) -> SiblingUses {
        let mut edges = SiblingUses::new();
        for (from, module) in &self.modules {
            for (path, offset) in &module.paths {
                let Some((to, _)) = self.resolve(from, path, 0) else {
                    continue;
                };
                let shared = from.iter().zip(&to).take_while(|(a, b)| a == b).count();
                if shared == from.len() || shared == to.len() {
                    continue;
                }
                let edge = (from[..=shared].to_vec(), to[..=shared].to_vec());
                edges.entry(edge).or_insert_with(|| {
                    let line = module.line(*offset);
                    format!("{}:{line} ({})", module.file.display(), path.join("::"))
                });
            }
        }
        edges
    }
}

/// The cycles among `edges`: for each edge on a cycle, the shortest cycle through it, starting at
/// its smallest module.
pub fn cycles(edges: &SiblingUses) -> BTreeSet<Vec<ModulePath>> {
    let mut next: BTreeMap<&ModulePath, Vec<&ModulePath>> = BTreeMap::new();
    for (a, b) in edges.keys() {
        next.entry(a).or_default().push(b);
    }
    let mut found = BTreeSet::new();
    for (a, b) in edges.keys() {
        // Breadth first from `b` back to `a`.
        let mut came_from: BTreeMap<&ModulePath, &ModulePath> = BTreeMap::new();
        let mut queue = std::collections::VecDeque::from([b]);
        while let Some(m) = queue.pop_front() {
            if m == a {
                break;
            }
            for &n in next.get(m).into_iter().flatten() {
                if n != b && !came_from.contains_key(n) {
                    came_from.insert(n, m);
                    queue.push_back(n);
                }
            }
        }
        if a != b && !came_from.contains_key(a) {
            continue;
        }
        let mut cycle = vec![a.clone()];
        let mut m = a;
        while m != b {
            m = came_from[m];
            cycle.push(m.clone());
        }
        cycle.reverse();
        let start = (0..cycle.len()).min_by_key(|&i| &cycle[i]).unwrap();
        cycle.rotate_left(start);
        found.insert(cycle);
    }
    found
}

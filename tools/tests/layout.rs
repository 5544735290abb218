//! The layout rules of `tools/src` and `python/src` (`docs/architecture.md`, issue 13), checked
//! on the source:
//! - only `cli/` and `main.rs` print, draw progress bars or import the CLI: no other file may
//!   contain `crate::cli`, `beamtools::cli`, `println!`, `print!`, `eprintln!`, `eprint!` or
//!   `indicatif` (comments, string literals and `#[cfg(test)]` items aside: a test may print
//!   what it measured);
//! - no function is longer than [`MAX_FN_LINES`] lines (from its `fn` line to its closing
//!   brace), found by a small scanner that skips comments, strings and char literals and
//!   matches braces.
//!
//! Each test fails with the full list of offenders (file:line), so the remaining work is
//! visible in one run.

use std::path::{Path, PathBuf};

/// Longest function allowed (lines, `fn` to closing brace).
const MAX_FN_LINES: usize = 80;

/// Patterns only `cli/` and `main.rs` may contain.
const CLI_ONLY: [&str; 7] = [
    "crate::cli",
    "beamtools::cli",
    "println!",
    "print!",
    "eprintln!",
    "eprint!",
    "indicatif",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

fn sources() -> Vec<(String, String)> {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = sources_under(&manifest.join("src"), "");
    assert!(
        out.len() > 10,
        "tools/src not found at {}",
        manifest.join("src").display()
    );
    // The Python package's crate (a member of this workspace) keeps the same rules.
    out.extend(sources_under(
        &manifest.join("../python/src"),
        "../python/src/",
    ));
    out
}

/// Every `.rs` file under `root`, as (`prefix` + path relative to `root`, text).
fn sources_under(root: &Path, prefix: &str) -> Vec<(String, String)> {
    let mut files = Vec::new();
    if root.is_dir() {
        rust_files(root, &mut files);
    }
    files
        .into_iter()
        .map(|p| {
            let rel = p
                .strip_prefix(root)
                .unwrap()
                .to_string_lossy()
                .replace('\\', "/");
            (
                format!("{prefix}{rel}"),
                std::fs::read_to_string(&p).unwrap(),
            )
        })
        .collect()
}

/// The code of `src` with comments, string literals and char literals blanked out (replaced
/// by spaces; newlines kept, so line numbers stay).
fn code_only(src: &str) -> Vec<char> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::with_capacity(c.len());
    let mut i = 0;
    let blank = |out: &mut Vec<char>, s: &[char]| {
        out.extend(s.iter().map(|&ch| if ch == '\n' { '\n' } else { ' ' }))
    };
    while i < c.len() {
        let end = literal_end(&c, i);
        if end > i {
            blank(&mut out, &c[i..end]);
            i = end;
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

/// `code` with every item that follows a `#[cfg(test)]` attribute (up to the end of its
/// braced body) blanked out.
fn without_test_items(mut code: Vec<char>) -> Vec<char> {
    let attr: Vec<char> = "#[cfg(test)]".chars().collect();
    let mut i = 0;
    while i + attr.len() <= code.len() {
        if !code[i..].starts_with(&attr) {
            i += 1;
            continue;
        }
        let from = i + attr.len();
        let Some(open) = (from..code.len()).find(|&k| code[k] == '{' || code[k] == ';') else {
            break;
        };
        let mut depth = 0i32;
        let mut end = open + 1; // an item without a body (`use …;`) ends at its `;`
        for (k, &ch) in code
            .iter()
            .enumerate()
            .skip(open)
            .take_while(|_| code[open] == '{')
        {
            depth += i32::from(ch == '{') - i32::from(ch == '}');
            if depth == 0 {
                end = k + 1;
                break;
            }
        }
        for ch in &mut code[i..end] {
            if *ch != '\n' {
                *ch = ' ';
            }
        }
        i = end;
    }
    code
}

/// If a comment, string or char literal starts at `i`, the index just past it; else `i`.
fn literal_end(c: &[char], i: usize) -> usize {
    let at = |k: usize| c.get(k).copied().unwrap_or('\0');
    let find = |from: usize, pat: &[char]| {
        (from..c.len())
            .find(|&k| c[k..].starts_with(pat))
            .map_or(c.len(), |k| k + pat.len())
    };
    match (at(i), at(i + 1)) {
        ('/', '/') => find(i, &['\n']) - 1,
        ('/', '*') => find(i + 2, &['*', '/']),
        ('"', _) => string_end(c, i + 1),
        ('r', '"') | ('r', '#') if !ident_char(at(i.wrapping_sub(1))) => raw_string_end(c, i),
        ('b', '"') if !ident_char(at(i.wrapping_sub(1))) => string_end(c, i + 2),
        ('\'', '\\') => find(i + 2, &['\'']),
        ('\'', _) if at(i + 2) == '\'' => i + 3,
        _ => i,
    }
}

fn ident_char(ch: char) -> bool {
    ch.is_alphanumeric() || ch == '_'
}

/// Past the closing quote of a string whose body starts at `i` (backslash escapes).
fn string_end(c: &[char], mut i: usize) -> usize {
    while i < c.len() {
        match c[i] {
            '\\' => i += 2,
            '"' => return i + 1,
            _ => i += 1,
        }
    }
    c.len()
}

/// Past the end of a raw string `r#*"…"#*` starting at `i` (or `i + 1` if not a raw string).
fn raw_string_end(c: &[char], i: usize) -> usize {
    let hashes = c[i + 1..].iter().take_while(|&&ch| ch == '#').count();
    if c.get(i + 1 + hashes) != Some(&'"') {
        return i + 1;
    }
    let mut close = vec!['"'];
    close.extend(std::iter::repeat_n('#', hashes));
    let body = i + 2 + hashes;
    (body..c.len())
        .find(|&k| c[k..].starts_with(&close))
        .map_or(c.len(), |k| k + close.len())
}

fn line_of(code: &[char], i: usize) -> usize {
    code[..i].iter().filter(|&&ch| ch == '\n').count() + 1
}

/// (name, first line, length in lines) of every function with a body in `code`.
fn functions(code: &[char]) -> Vec<(String, usize, usize)> {
    let mut out = Vec::new();
    for i in 0..code.len().saturating_sub(3) {
        let is_fn = code[i..].starts_with(&['f', 'n'])
            && code[i + 2].is_whitespace()
            && (i == 0 || !ident_char(code[i - 1]));
        if !is_fn {
            continue;
        }
        let name: String = code[i + 2..]
            .iter()
            .skip_while(|ch| ch.is_whitespace())
            .take_while(|&&ch| ident_char(ch))
            .collect();
        if let Some(end) = body_end(code, i) {
            let (first, last) = (line_of(code, i), line_of(code, end));
            out.push((name, first, last - first + 1));
        }
    }
    out
}

/// The index of the closing brace of the body of the `fn` at `i` (`None`: no body).
fn body_end(code: &[char], i: usize) -> Option<usize> {
    let mut depth = 0i32;
    let mut k = i;
    while k < code.len() {
        match code[k] {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ';' if depth == 0 => return None,
            '{' if depth == 0 => break,
            _ => {}
        }
        k += 1;
    }
    let mut braces = 0i32;
    for (j, &ch) in code.iter().enumerate().skip(k) {
        match ch {
            '{' => braces += 1,
            '}' => {
                braces -= 1;
                if braces == 0 {
                    return Some(j);
                }
            }
            _ => {}
        }
    }
    None
}

fn cli_side(rel: &str) -> bool {
    rel == "main.rs" || rel.starts_with("cli/")
}

#[test]
fn only_cli_prints_or_imports_cli() {
    let mut offenders = Vec::new();
    for (rel, src) in sources().iter().filter(|(rel, _)| !cli_side(rel)) {
        let code: String = without_test_items(code_only(src)).into_iter().collect();
        for (n, line) in code.lines().enumerate() {
            for pat in CLI_ONLY.iter().filter(|p| line.contains(*p)) {
                offenders.push(format!("{rel}:{}: {pat}", n + 1));
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "{} uses of CLI-only code outside cli/ and main.rs:\n{}",
        offenders.len(),
        offenders.join("\n")
    );
}

#[test]
fn no_function_is_over_80_lines() {
    let mut offenders = Vec::new();
    for (rel, src) in sources() {
        for (name, line, len) in functions(&code_only(&src)) {
            if len > MAX_FN_LINES {
                offenders.push(format!("{rel}:{line}: fn {name}: {len} lines"));
            }
        }
    }
    assert!(
        offenders.is_empty(),
        "{} functions over {MAX_FN_LINES} lines:\n{}",
        offenders.len(),
        offenders.join("\n")
    );
}

#[test]
fn the_scanner_skips_literals_and_measures_bodies() {
    let src = "fn a() {\n    let s = \"}{ println!\";\n    let c = '}';\n    // println!(\"{\")\n}\nfn b<'x>(v: &'x [u8]) -> usize where u8: Copy { v.len() }\ntrait T { fn c(&self); }\nfn d() { let r = r#\"}\"#; }\n#[cfg(test)]\nuse std::fmt;\n#[cfg(test)]\nmod t { fn e() { eprintln!(\"x\"); } }\n";
    let code = code_only(src);
    let text: String = code.iter().collect();
    let before_tests = &text[..text.find("#[cfg(test)]").unwrap()];
    assert!(!before_tests.contains("println!"), "{text}");
    let outside: String = without_test_items(code.clone()).into_iter().collect();
    assert!(
        !outside.contains("eprintln!") && outside.contains("fn d()"),
        "{outside}"
    );
    assert_eq!(outside.lines().count(), text.lines().count());
    let f = functions(&code);
    let names: Vec<_> = f.iter().map(|(n, l, len)| (n.as_str(), *l, *len)).collect();
    assert_eq!(names, [("a", 1, 5), ("b", 6, 1), ("d", 8, 1), ("e", 12, 1)]);
}

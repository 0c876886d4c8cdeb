//! A nesting-depth and size check run on YAML text before `serde_yaml` parses it.
//!
//! `serde_yaml` refuses documents nested deeper than 128, but only after libyaml has
//! scanned the whole document, and libyaml's scanner is quadratic in the flow nesting
//! depth: `[[[…]]]` 100,000 deep took a minute to reject. This check pulls the same
//! parser's events one at a time (libyaml reads lazily) and stops at the first collection
//! nested deeper than serde_yaml would accept, so it refuses exactly what serde_yaml would
//! refuse, after reading only the document's first 128 levels. A well-formed document costs
//! one extra linear pass of the tokenizer; a syntax error is left for serde_yaml to report.
//!
//! The same pass counts the document's values: serde_yaml holds every event of a document
//! and then a `Value` per node, about 240 bytes per value (a 10^6-block list, 4 x 10^6
//! values, took 950 MB and 8 s), so a document of more than [`MAX_YAML_VALUES`] is
//! refused before it is parsed.

use std::mem::MaybeUninit;

use thiserror::Error;

/// The deepest nesting accepted: serde_yaml's own recursion limit.
pub const MAX_YAML_DEPTH: usize = 128;

/// The most values (scalars, sequences, mappings) a document may hold: about 700 MB in
/// serde_yaml, a list of 750,000 blocks — more than the planner takes by default.
pub const MAX_YAML_VALUES: usize = 3_000_000;

/// YAML refused before parsing.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum YamlRefused {
    #[error("YAML nested more than {MAX_YAML_DEPTH} levels deep (line {line})")]
    TooDeep { line: usize },
    #[error("YAML of more than {MAX_YAML_VALUES} values (line {line}): too large to read")]
    TooManyValues { line: usize },
}

/// Refuses YAML (or JSON) text nested deeper than [`MAX_YAML_DEPTH`] or holding more than
/// [`MAX_YAML_VALUES`] values, reading no further than the point where it is refused.
pub fn check(text: &str) -> Result<(), YamlRefused> {
    let mut parser = MaybeUninit::<unsafe_libyaml::yaml_parser_t>::uninit();
    // SAFETY: the libyaml calls below follow serde_yaml's own use of them
    // (serde_yaml/src/libyaml/parser.rs): the parser is initialised before use and
    // deleted exactly once; each event is deleted after it is read; `text` outlives the
    // parser, which only reads it.
    unsafe {
        let parser = parser.as_mut_ptr();
        if unsafe_libyaml::yaml_parser_initialize(parser).fail {
            // Out of memory for a parser: let serde_yaml meet (and report) the same.
            return Ok(());
        }
        unsafe_libyaml::yaml_parser_set_encoding(parser, unsafe_libyaml::YAML_UTF8_ENCODING);
        unsafe_libyaml::yaml_parser_set_input_string(parser, text.as_ptr(), text.len() as u64);
        let (mut depth, mut values) = (0usize, 0usize);
        let result = loop {
            let mut event = MaybeUninit::<unsafe_libyaml::yaml_event_t>::uninit();
            let event = event.as_mut_ptr();
            if unsafe_libyaml::yaml_parser_parse(parser, event).fail {
                break Ok(());
            }
            let (kind, line) = ((*event).type_, (*event).start_mark.line as usize + 1);
            unsafe_libyaml::yaml_event_delete(event);
            if matches!(
                kind,
                unsafe_libyaml::YAML_SEQUENCE_START_EVENT
                    | unsafe_libyaml::YAML_MAPPING_START_EVENT
                    | unsafe_libyaml::YAML_SCALAR_EVENT
                    | unsafe_libyaml::YAML_ALIAS_EVENT
            ) {
                values += 1;
                if values > MAX_YAML_VALUES {
                    break Err(YamlRefused::TooManyValues { line });
                }
            }
            match kind {
                unsafe_libyaml::YAML_SEQUENCE_START_EVENT
                | unsafe_libyaml::YAML_MAPPING_START_EVENT => {
                    depth += 1;
                    if depth > MAX_YAML_DEPTH {
                        break Err(YamlRefused::TooDeep { line });
                    }
                }
                unsafe_libyaml::YAML_SEQUENCE_END_EVENT
                | unsafe_libyaml::YAML_MAPPING_END_EVENT => depth = depth.saturating_sub(1),
                unsafe_libyaml::YAML_STREAM_END_EVENT => break Ok(()),
                _ => {}
            }
        };
        unsafe_libyaml::yaml_parser_delete(parser);
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deep_nesting_is_refused_quickly_and_what_serde_yaml_reads_passes() {
        let t = std::time::Instant::now();
        let deep = format!("name: {}{}", "[".repeat(100_000), "]".repeat(100_000));
        assert_eq!(check(&deep), Err(YamlRefused::TooDeep { line: 1 }));
        let maps = format!(
            "a:\n  b: {}1{}",
            "{a: ".repeat(100_000),
            "}".repeat(100_000)
        );
        assert_eq!(check(&maps), Err(YamlRefused::TooDeep { line: 2 }));
        let block = format!("a:\n{}x\n", "- ".repeat(100_000));
        assert!(check(&block).is_err());
        assert!(t.elapsed().as_millis() < 1000, "{:?}", t.elapsed());
        let many = "[".repeat(200);
        for text in [
            format!("x: {}{}", "[".repeat(120), "]".repeat(120)),
            format!("a: \"{many}\"\nb: '{many}'\n# {many}\nc: |\n  {many}\n"),
            // Not YAML at all: serde_yaml says why.
            "a: [\n".to_string(),
        ] {
            assert_eq!(check(&text), Ok(()), "{text}");
        }
    }

    #[test]
    fn a_document_of_too_many_values_is_refused_before_parsing() {
        let at_limit = format!("[{}]", "1,".repeat(MAX_YAML_VALUES - 1));
        assert_eq!(check(&at_limit), Ok(()));
        let over = format!("[{}]", "1,".repeat(MAX_YAML_VALUES));
        assert_eq!(check(&over), Err(YamlRefused::TooManyValues { line: 1 }));
    }
}

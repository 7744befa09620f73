//! The one XML parser entry point: models, force-set files, ExternalLoads files and tool
//! setups all go through [`parse`], so they share one policy for what an XML file may hold.
//!
//! A document type declaration is read (some exporters write one), but an entity
//! declaration in it is refused before parsing. roxmltree expands internal entities as it
//! parses: one entity of a megabyte referenced a few thousand times asks for gigabytes (the
//! "billion laughs" family of attacks, and its quadratic variant that stays under
//! roxmltree's own depth limits). OpenSim files never declare entities, so refusing them
//! costs nothing and keeps the memory a file can demand proportional to its size.
//!
//! Before parsing, one linear scan ([`check_shape`]) refuses an element with more than
//! [`crate::limits::MAX_XML_ATTRIBUTES`] attributes: roxmltree compares each attribute with
//! every earlier one of its element (quadratic in the attributes of one element: 200,000 of
//! them took over a minute). Nesting depth is the model reader's check (it is the reader
//! that recurses), against [`crate::limits::MAX_XML_DEPTH`].

use crate::error::Error;
use roxmltree::{Document, ParsingOptions};

/// Parses `text` (read from `source`, named in errors). Errors are [`Error::Xml`] with the
/// 1-based line and column: malformed XML, a file that ends inside an element (reported
/// where it ends), or an entity declaration (reported at its `<!ENTITY`).
pub(crate) fn parse<'i>(text: &'i str, source: &str) -> crate::Result<Document<'i>> {
    check_shape(text, source)?;
    if let Some(at) = entity_declaration(text) {
        let (line, column) = line_column(text, at);
        // The entity's name only (its value may be megabytes), itself cut at 40 characters.
        let name: String = text[at + "<!ENTITY".len()..]
            .split_whitespace()
            .next()
            .unwrap_or("")
            .chars()
            .take(40)
            .collect();
        return Err(Error::Xml {
            file: source.to_string(),
            line,
            column,
            message: format!(
                "the document type declares an entity (`<!ENTITY {name} …`): musculo does not \
                 expand XML entities (a few bytes of them can ask for gigabytes); write the \
                 text in place of each reference and remove the declaration"
            ),
        });
    }
    Document::parse_with_options(
        text,
        ParsingOptions {
            allow_dtd: true,
            ..ParsingOptions::default()
        },
    )
    .map_err(|e| {
        let pos = e.pos();
        let (line, column, message) = match e {
            // roxmltree gives these no position: the problem is where the text ends.
            roxmltree::Error::UnexpectedEndOfStream | roxmltree::Error::UnclosedRootNode => {
                let (line, column) = line_column(text, text.len());
                (
                    line,
                    column,
                    format!("{e} (the file ends inside an element: is it truncated?)"),
                )
            }
            _ => (pos.row, pos.col, e.to_string()),
        };
        Error::Xml {
            file: source.to_string(),
            line,
            column,
            message,
        }
    })
}

/// Refuses, in one pass over `text`, an element with more than
/// [`crate::limits::MAX_XML_ATTRIBUTES`] attributes ([`Error::Limit`] at the element's line
/// and column).
/// Comments, CDATA sections, processing instructions and the document type declaration are
/// skipped; text that is not well-formed is left for the parser to report.
fn check_shape(text: &str, source: &str) -> crate::Result<()> {
    use crate::limits::MAX_XML_ATTRIBUTES;
    let b = text.as_bytes();
    let refuse = |at: usize, message: String| {
        let (line, column) = line_column(text, at);
        Err(crate::limits::exceeded(
            source,
            &format!("line {line}, column {column}"),
            message,
        ))
    };
    // The end of `close` searched from `from`; None: the text ends first.
    let skip_to =
        |from: usize, close: &str| text[from..].find(close).map(|i| from + i + close.len());
    let mut i = 0;
    while let Some(lt) = b[i..].iter().position(|&c| c == b'<').map(|k| i + k) {
        let rest = &b[lt + 1..];
        let next = if rest.starts_with(b"!--") {
            skip_to(lt + 4, "-->")
        } else if rest.starts_with(b"![CDATA[") {
            skip_to(lt + 9, "]]>")
        } else if rest.starts_with(b"?") {
            skip_to(lt + 2, "?>")
        } else if rest.starts_with(b"!") {
            // a declaration: to its `>`, past an internal subset in brackets and quotes
            let (mut brackets, mut quote, mut end) = (0usize, 0u8, None);
            for (k, &c) in rest.iter().enumerate() {
                if quote != 0 {
                    if c == quote {
                        quote = 0;
                    }
                    continue;
                }
                match c {
                    b'"' | b'\'' => quote = c,
                    b'[' => brackets += 1,
                    b']' => brackets = brackets.saturating_sub(1),
                    b'>' if brackets == 0 => {
                        end = Some(lt + 1 + k + 1);
                        break;
                    }
                    _ => {}
                }
            }
            end
        } else if rest.starts_with(b"/") {
            skip_to(lt + 2, ">")
        } else {
            // a start tag: its attributes are its `=` outside quoted values
            let (mut attributes, mut quote, mut end) = (0usize, 0u8, None);
            for (k, &c) in rest.iter().enumerate() {
                if quote != 0 {
                    if c == quote {
                        quote = 0;
                    }
                    continue;
                }
                match c {
                    b'"' | b'\'' => quote = c,
                    b'=' => {
                        attributes += 1;
                        if attributes > MAX_XML_ATTRIBUTES {
                            return refuse(
                                lt,
                                format!(
                                    "the element has more than {MAX_XML_ATTRIBUTES} attributes \
                                     (musculo::limits::MAX_XML_ATTRIBUTES)"
                                ),
                            );
                        }
                    }
                    b'>' => {
                        end = Some(lt + 1 + k + 1);
                        break;
                    }
                    _ => {}
                }
            }
            end
        };
        match next {
            Some(n) => i = n,
            None => break, // the text ends inside markup: the parser says where
        }
    }
    Ok(())
}

/// Byte offset of the first `<!ENTITY` after a `<!DOCTYPE`, if any. XML's grammar spells
/// both exactly so (case-sensitive, no space after `<!`), and entities can only be declared
/// inside the document type declaration, so a document without this pair declares none.
/// (The same text inside a comment after a DOCTYPE is refused too: harmless and rare.)
fn entity_declaration(text: &str) -> Option<usize> {
    let doctype = text.find("<!DOCTYPE")?;
    text[doctype..].find("<!ENTITY").map(|i| doctype + i)
}

/// 1-based line and column (in characters) of byte offset `at` of `text`.
pub(crate) fn line_column(text: &str, at: usize) -> (u32, u32) {
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (
        u32::try_from(line).unwrap_or(u32::MAX),
        u32::try_from(column).unwrap_or(u32::MAX),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_entity_declaration_is_refused_at_its_line_and_column() {
        let text = "<?xml version=\"1.0\"?>\n<!DOCTYPE a [\n  <!ENTITY big \"xxxx\">\n]>\n\
                    <a>&big;&big;</a>\n";
        match parse(text, "e.xml") {
            Err(Error::Xml {
                file,
                line,
                column,
                message,
            }) => {
                assert_eq!((file.as_str(), line, column), ("e.xml", 3, 3));
                assert!(message.contains("<!ENTITY big"), "{message}");
            }
            other => panic!("expected an XML error, got {other:?}"),
        }
    }

    #[test]
    fn a_dtd_without_entities_and_plain_documents_parse() {
        let doc = parse("<!DOCTYPE a>\n<a><b>1</b></a>", "d.xml").unwrap();
        assert_eq!(doc.root_element().tag_name().name(), "a");
        // `<!ENTITY` as text in a document without a DOCTYPE is just text.
        let doc = parse("<a><!-- <!ENTITY x 'y'> --><b/></a>", "c.xml").unwrap();
        assert_eq!(doc.root_element().children().count(), 2);
    }

    #[test]
    fn a_truncated_file_is_reported_where_it_ends() {
        match parse("<a>\n  <b>\n    <c>1</c>", "t.xml") {
            Err(Error::Xml { line, column, .. }) => assert_eq!((line, column), (3, 13)),
            other => panic!("expected an XML error, got {other:?}"),
        }
    }

    #[test]
    fn many_attributes_are_refused_before_parsing() {
        use crate::limits::MAX_XML_ATTRIBUTES;
        let attrs: String = (0..=MAX_XML_ATTRIBUTES)
            .map(|i| format!(" a{i}='1'"))
            .collect();
        let text = format!("<a>\n <b{attrs}/></a>");
        match parse(&text, "x.xml") {
            Err(Error::Limit {
                location, message, ..
            }) => {
                assert_eq!(location, "line 2, column 2");
                assert!(message.contains("MAX_XML_ATTRIBUTES"), "{message}");
            }
            other => panic!("expected a limit error, got {other:?}"),
        }
        // At the limits, with comments, CDATA, a DOCTYPE and `=`/`>` inside values: accepted.
        let attrs: String = (0..MAX_XML_ATTRIBUTES)
            .map(|i| format!(" a{i}=\"x=>y\""))
            .collect();
        let ok = format!(
            "<?xml version='1.0'?><!DOCTYPE a [<!ELEMENT a ANY>]><!-- <b c='1'> -->{}<e{attrs}/>\
             <![CDATA[<x>]]>{}",
            "<a>".repeat(300),
            "</a>".repeat(300)
        );
        parse(&ok, "ok.xml").unwrap();
    }

    #[test]
    fn line_and_column_count_characters_from_one() {
        assert_eq!(line_column("ab\ncdé\nf", 0), (1, 1));
        assert_eq!(line_column("ab\ncdé\nf", 3), (2, 1));
        assert_eq!(line_column("ab\ncdé\nf", 7), (2, 4));
        assert_eq!(line_column("ab\ncdé\nf", 9), (3, 2));
    }
}

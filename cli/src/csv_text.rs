//! CSV text for the output files, written with the csv crate: a field that holds a comma, a
//! quote or a line break is quoted (a quote inside doubled), every record ends in `\n`, and every
//! record of a file has as many fields as its header. Numbers are formatted by the callers
//! ([`crate::output::fmt_num`]), so that each reads back to the same `f64`.

use anyhow::{Context, Result};

/// A CSV text being written, header first.
#[derive(Debug)]
pub(crate) struct CsvText {
    writer: csv::Writer<Vec<u8>>,
}

impl CsvText {
    /// A text starting with the `header` record.
    pub(crate) fn new<I, S>(header: I) -> Result<Self>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<[u8]>,
    {
        let writer = csv::WriterBuilder::new().terminator(csv::Terminator::Any(b'\n')).from_writer(Vec::new());
        let mut text = Self { writer };
        text.row(header)?;
        Ok(text)
    }

    /// Appends one record (as many fields as the header).
    pub(crate) fn row<I, S>(&mut self, fields: I) -> Result<()>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<[u8]>,
    {
        self.writer.write_record(fields).context("cannot write a CSV record")
    }

    /// The text written.
    pub(crate) fn finish(self) -> Result<String> {
        let bytes = self.writer.into_inner().map_err(|e| anyhow::anyhow!("cannot finish a CSV text: {}", e.error()))?;
        String::from_utf8(bytes).context("the CSV text is not UTF-8")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_quoted_only_when_needed_and_read_back() {
        let mut t = CsvText::new(["name", "value"]).unwrap();
        for name in ["mid", "a,b", "say \"x\"", "two\nlines", ""] {
            t.row([name, "1"]).unwrap();
        }
        let text = t.finish().unwrap();
        assert_eq!(text, "name,value\nmid,1\n\"a,b\",1\n\"say \"\"x\"\"\",1\n\"two\nlines\",1\n,1\n");
        let mut r = csv::Reader::from_reader(text.as_bytes());
        let names: Vec<String> = r.records().map(|rec| rec.unwrap()[0].to_string()).collect();
        assert_eq!(names, ["mid", "a,b", "say \"x\"", "two\nlines", ""]);
    }

    #[test]
    fn a_record_of_another_length_is_an_error() {
        let mut t = CsvText::new(["a", "b"]).unwrap();
        assert!(t.row(["1"]).is_err());
    }
}

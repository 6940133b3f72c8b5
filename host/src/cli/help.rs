//! `--help` for people: clap takes its texts from doc comments, which are written for
//! rustdoc; its link syntax (`[`Tuning::tap_s`]`) means nothing on a terminal, so every
//! help text and every possible value's help is rewritten to plain words once, here.

use std::marker::PhantomData;

use clap::builder::{EnumValueParser, PossibleValue, TypedValueParser};
use clap::{Arg, Command, ValueEnum};

/// Items of the library that doc comments link to, and what a person at the command
/// line knows them as (the flag that sets them); any other link is shown as its name.
const LINKS: &[(&str, &str)] = &[
    ("Tuning::stroke_speed_mps", "--speed"),
    ("Tuning::tap_s", "--tap-ms"),
    ("Tuning::shake_hz", "--shake-hz"),
    ("Tuning::shake_amplitude_mm", "--shake-mm"),
    ("Tuning::gap_s", "--gap-ms"),
    ("Mask", "--mask"),
];

/// `text` with every rustdoc link (`[`path::Item`]`, `[text](target)` excluded) written
/// as the flag it stands for, or as the item's last name in backticks.
pub fn plain(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(open) = rest.find("[`") {
        let inner = &rest[open + 2..];
        let Some(close) = inner.find("`]") else {
            break;
        };
        let item = &inner[..close];
        out.push_str(&rest[..open]);
        let shown = LINKS
            .iter()
            .find(|(link, _)| *link == item)
            .map(|(_, flag)| *flag)
            .unwrap_or_else(|| item.rsplit("::").next().unwrap_or(item));
        out.push('`');
        out.push_str(shown);
        out.push('`');
        rest = &inner[close + 2..];
    }
    out.push_str(rest);
    out
}

/// `cmd` and all its subcommands with every argument's help in [`plain`] words.
pub fn plain_command(cmd: Command) -> Command {
    let cmd = cmd.mut_args(plain_arg);
    let cmd = match cmd.get_about().map(|a| plain(&a.to_string())) {
        Some(about) => cmd.about(about),
        None => cmd,
    };
    let cmd = match cmd.get_long_about().map(|a| plain(&a.to_string())) {
        Some(about) => cmd.long_about(about),
        None => cmd,
    };
    cmd.mut_subcommands(plain_command)
}

fn plain_arg(arg: Arg) -> Arg {
    let arg = match arg.get_help().map(|h| plain(&h.to_string())) {
        Some(help) => arg.help(help),
        None => arg,
    };
    match arg.get_long_help().map(|h| plain(&h.to_string())) {
        Some(help) => arg.long_help(help),
        None => arg,
    }
}

/// clap's parser of a [`ValueEnum`], with each value's help (the variant's doc
/// comment) in [`plain`] words: `#[arg(value_parser = PlainEnum::<Gesture>::new())]`.
#[derive(Debug, Clone, Copy)]
pub struct PlainEnum<E>(PhantomData<E>);

impl<E> PlainEnum<E> {
    /// The parser.
    pub fn new() -> Self {
        PlainEnum(PhantomData)
    }
}

impl<E: ValueEnum + Clone + Send + Sync + 'static> TypedValueParser for PlainEnum<E> {
    type Value = E;

    fn parse_ref(
        &self,
        cmd: &Command,
        arg: Option<&Arg>,
        value: &std::ffi::OsStr,
    ) -> Result<E, clap::Error> {
        EnumValueParser::<E>::new().parse_ref(cmd, arg, value)
    }

    fn possible_values(&self) -> Option<Box<dyn Iterator<Item = PossibleValue> + '_>> {
        Some(Box::new(
            E::value_variants()
                .iter()
                .filter_map(ValueEnum::to_possible_value)
                .map(|v| match v.get_help().map(|h| plain(&h.to_string())) {
                    Some(help) => v.help(help),
                    None => v,
                }),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::plain;

    #[test]
    fn links_become_flags_or_names() {
        assert_eq!(
            plain("over 1.2 s ([`Tuning::stroke_speed_mps`] sets its speed)"),
            "over 1.2 s (`--speed` sets its speed)"
        );
        assert_eq!(plain("outline from [`Mask`]"), "outline from `--mask`");
        assert_eq!(plain("see [`crate::a::Other`]."), "see `Other`.");
        assert_eq!(plain("no links, `code` [x]"), "no links, `code` [x]");
    }
}

//! The serial line protocol (USART2, 115200 8N1): pure parsing and formatting.
//!
//! Owns the line assembler, the command grammar and the reply format; may use
//! [`crate::motion::run`] (directions, run capacity), [`crate::kinematics`] and [`crate::util`].
//!
//! - [`line::LineAssembler`] turns received bytes into lines (`\r`, `\n` or `\r\n`) and stop
//!   keys (Ctrl-C, Esc), consumes terminal escape sequences, and rejects over-long lines and lines
//!   hit by a receive error as a whole; [`rx`] is the receive loop the USART interrupt runs;
//! - [`Command::parse`] turns a line into a validated [`Command`] (units: metres, m/s, rad/s,
//!   degrees for measured headings, Hz);
//! - [`unit`](mod@unit) reads a measured length or heading with its unit (`41.8mm`, `2deg`), for the
//!   parser and the PC console alike;
//! - [`outcome`] words what a run command did (typed [`outcome::Outcome`] values);
//! - [`refusal`] words the session's refusals (typed [`refusal::Refusal`] values, one error code
//!   each);
//! - [`reply`] writes `ok …` / `err <code>: <message>` lines with `core::fmt::Write`;
//! - [`token`] writes and reads what a program relies on in the board's lines (event tags, the
//!   wiring verdict, the `calibrate` table's rows), for the board and the PC console alike;
//! - [`record`] writes a run's full record (`record`) losslessly and reads it back on a host, and
//!   the `version` reply.
//!
//! Nothing here touches hardware or allocates; [`crate::session`] executes the commands. The
//! command table and error codes are documented in `docs/protocol.md`.

pub mod command;
mod command_values;
mod command_write;
pub mod line;
pub mod number;
pub mod outcome;
pub mod param;
pub mod parse_error;
pub mod record;
pub mod refusal;
pub mod reply;
pub mod rx;
pub mod stream;
pub mod token;
pub mod unit;

pub use command::{Command, ParseError};
pub use line::{Echo, LINE_MAX, LineAssembler, LineError, LineEvent, StopKey};
pub use param::{PARAMS, ParamGroup, ParamName, ParamSpec, ValueKind};
pub use reply::{EOL, ErrorCode, FinalLine, ReplyLine};

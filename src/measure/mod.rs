//! The measuring tools behind `termtrace bench --preview`: the live preview run in a
//! pseudo-terminal and timed as a user sees it (`preview`), and a real OpenSSH connection
//! through a throttled loopback link to run it over (`ssh_link`). The tests use them too.

pub mod preview;
pub mod ssh_link;

//! The page `kdtrace serve` serves, compiled into the binary: plain HTML, CSS and JavaScript with
//! no build step, so the server needs nothing beside itself.
pub const INDEX_HTML: &str = include_str!("page/index.html");
pub const APP_JS: &str = include_str!("page/app.js");
pub const STYLE_CSS: &str = include_str!("page/style.css");

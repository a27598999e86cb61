//! Any text: `parse` must return (never panic); a parsed program must convert
//! and emit without panicking, and its emitted text must parse again.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(program) = gcode::parse(text) {
        let _ = program.to_core_blocks(&gcode::CoreOptions::default());
        let emitted = gcode::emit(&program);
        let _ = gcode::parse(&emitted);
    }
});

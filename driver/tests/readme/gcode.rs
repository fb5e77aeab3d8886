use driver::gcode::{GcodePath, MachineSpec};
use driver::{Hub, HubConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let hub = Hub::new(HubConfig::default())?; // virtual clock
    let x = hub.start_sd(0, 1, 2)?;
    let y = hub.start_sd(3, 4, 5)?;
    hub.set_input(0, true)?;
    hub.set_input(3, true)?;
    let spec = MachineSpec::from_toml_str(
        "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 200.0\nmax_accel_mm_s2 = 2000.0\n\
         [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 200.0\nmax_accel_mm_s2 = 2000.0\n\
         [planner]\njunction_deviation_mm = 0.01\narc_tolerance_mm = 0.002\n",
    )?;
    // Lines and an arc, blended through their junctions with continuous
    // acceleration; a push to a full queue waits (here: runs the clock).
    let mut program = GcodePath::new(&hub, &[&x, &y], &spec)?;
    program.run_program("G21 G90 G64\nG1 X10 F3000\nG2 X20 Y0 I5 J0\nG1 Y10\nM2\n")?;
    assert_eq!((x.position(), y.position()), (1_600, 800)); // 20 mm, 10 mm at 80 steps/mm
    let done = program.finish()?;
    assert_eq!(done.tag, 4); // the last line that moved
    Ok(())
}

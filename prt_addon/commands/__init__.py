"""The command line: `python -m prt_addon COMMAND ...` (bpy module) and `blender -b FILE -c prt COMMAND ...`
(a real Blender) share one parser (cli.py) and one module per command, each with add_parser(commands) and
run(args, in_blender)."""

"""The commands of `inshade`, one module per group: each adds its parsers (``add_parser`` or
``add_parsers``) and holds the functions they run. inshade/cli.py assembles them and runs the
command; heavy imports (torch, GL, the web page) stay inside the command functions, so the parser
loads without them."""

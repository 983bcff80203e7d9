"""One module per `quadtank` subcommand that grew beyond a handler in cli.py."""

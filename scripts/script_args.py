"""Command-line options shared by the scripts/*.py tables: `take(args, flag, default)` removes
`flag VALUE` from `args` and returns VALUE, or `default` when the flag is absent."""


def take(args, flag, default):
    if flag not in args:
        return default
    i = args.index(flag)
    value = args[i + 1]
    del args[i : i + 2]
    return value

# bash completion for ellroll: source it, or install it as
# share/bash-completion/completions/ellroll
_ellroll() {
    local current=${COMP_WORDS[COMP_CWORD]} previous=${COMP_WORDS[COMP_CWORD-1]}
    local commands="run check merge summary modes methods inputs"
    if [ "$COMP_CWORD" -eq 1 ]; then
        COMPREPLY=($(compgen -W "$commands --help --version" -- "$current"))
        return
    fi
    case "$previous" in
        --format) COMPREPLY=($(compgen -W "table csv json" -- "$current")); return ;;
        --threads|--shard) return ;;
        -o|--output) COMPREPLY=($(compgen -f -X '!*.h5' -- "$current")); return ;;
    esac
    case "${COMP_WORDS[1]}" in
        run) COMPREPLY=($(compgen -W "-o --output --overwrite --resume --threads --shard -q --quiet --timings --help" \
                          -- "$current") $(compgen -f -X '!*.nml' -- "$current")) ;;
        check|modes) COMPREPLY=($(compgen -W "-o --output --help" -- "$current") \
                                $(compgen -f -X '!*.nml' -- "$current")) ;;
        merge) COMPREPLY=($(compgen -W "--overwrite --help" -- "$current") $(compgen -f -X '!*.h5' -- "$current")) ;;
        summary) COMPREPLY=($(compgen -W "--format --help" -- "$current") $(compgen -f -X '!*.h5' -- "$current")) ;;
        *) COMPREPLY=($(compgen -W "--help" -- "$current")) ;;
    esac
}
complete -o filenames -o bashdefault -F _ellroll ellroll

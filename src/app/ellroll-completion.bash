# bash completion for ellroll: source it, or install it as
# share/bash-completion/completions/ellroll
_ellroll_files() {
    # files matching the pattern (an input's .nml, an output's .h5) and every
    # folder (-o filenames ends a folder with '/', so that the path goes on)
    local pattern=$1 current=$2 IFS=$'\n'
    COMPREPLY+=($(compgen -f -X "!$pattern" -- "$current"))
    COMPREPLY+=($(compgen -d -- "$current"))
}
_ellroll() {
    local current=${COMP_WORDS[COMP_CWORD]} previous=${COMP_WORDS[COMP_CWORD-1]}
    local commands="run check merge summary modes methods inputs"
    COMPREPLY=()
    if [ "$COMP_CWORD" -eq 1 ]; then
        COMPREPLY=($(compgen -W "$commands --help --version" -- "$current"))
        return
    fi
    case "$previous" in
        --format) COMPREPLY=($(compgen -W "table csv json" -- "$current")); return ;;
        --threads|--shard) return ;;
        -o|--output) _ellroll_files '*.h5' "$current"; return ;;
    esac
    if [[ "$current" == -* ]]; then
        case "${COMP_WORDS[1]}" in
            run) COMPREPLY=($(compgen -W "-o --output --overwrite --resume --threads --shard -q --quiet --timings \
                              --help" -- "$current")) ;;
            check) COMPREPLY=($(compgen -W "-o --output --shard --threads --help" -- "$current")) ;;
            merge) COMPREPLY=($(compgen -W "--overwrite --help" -- "$current")) ;;
            summary) COMPREPLY=($(compgen -W "--format --suite --help" -- "$current")) ;;
            *) COMPREPLY=($(compgen -W "--help" -- "$current")) ;;
        esac
        return
    fi
    case "${COMP_WORDS[1]}" in
        run|check|modes) _ellroll_files '*.nml' "$current" ;;
        merge|summary) _ellroll_files '*.h5' "$current" ;;
    esac
}
complete -o filenames -F _ellroll ellroll

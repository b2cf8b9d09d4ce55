# bash completion for hcrctl: printed by `hcrctl completion bash`; bash 3.2 or newer.
# Click's protocol (_HCRCTL_COMPLETE=bash_complete, COMP_WORDS, COMP_CWORD), with the words bash
# split at a COMP_WORDBREAKS character (the ':' of sim://) joined again from COMP_LINE.

if [ -z "${BASH_VERSION-}" ]; then
    echo "hcrctl: this is the bash completion script; for zsh or fish: hcrctl completion zsh|fish" >&2
    return 1 2>/dev/null || exit 1
fi
if ((BASH_VERSINFO[0] < 3 || (BASH_VERSINFO[0] == 3 && BASH_VERSINFO[1] < 2))); then
    echo "hcrctl: completion needs bash 3.2 or newer, this is bash $BASH_VERSION" >&2
    return 1 2>/dev/null || exit 1
fi

_hcrctl_completion_words() {
    # Sets _hcrctl_completion_cword and the array _hcrctl_completion_argv: COMP_WORDS, rejoined where
    # COMP_LINE has no blank between two of them. Without COMP_LINE, COMP_WORDS as they are.
    local line=${COMP_LINE-} blanks i j=-1
    _hcrctl_completion_argv=()
    _hcrctl_completion_cword=0
    if [[ -z $line ]]; then
        _hcrctl_completion_argv=("${COMP_WORDS[@]}")
        _hcrctl_completion_cword=$COMP_CWORD
        return
    fi
    for ((i = 0; i < ${#COMP_WORDS[@]}; i++)); do
        blanks=${line%%[![:blank:]]*}
        line=${line#"$blanks"}
        if ((j < 0)) || [[ -n $blanks || $line != "${COMP_WORDS[i]}"* ]]; then
            ((j++))
            _hcrctl_completion_argv[j]=""
        fi
        _hcrctl_completion_argv[j]+=${COMP_WORDS[i]}
        line=${line#"${COMP_WORDS[i]}"}
        if ((i == COMP_CWORD)); then
            _hcrctl_completion_cword=$j
        fi
    done
}

_hcrctl_completion() {
    local IFS=$'\n'
    local response completion type value cur trim=""
    local -a _hcrctl_completion_argv
    local _hcrctl_completion_cword

    _hcrctl_completion_words
    cur=${_hcrctl_completion_argv[_hcrctl_completion_cword]}
    # bash replaces only the text after the word's last colon: answers must drop what precedes it.
    if [[ $cur == *:* && $COMP_WORDBREAKS == *:* ]]; then
        trim=${cur%"${cur##*:}"}
    fi
    response=$(env COMP_WORDS="${_hcrctl_completion_argv[*]}" COMP_CWORD=$_hcrctl_completion_cword \
_HCRCTL_COMPLETE=bash_complete $1)

    for completion in $response; do
        IFS=',' read -r type value <<< "$completion"

        if [[ $type == 'dir' ]]; then
            COMPREPLY=()
            if ((BASH_VERSINFO[0] >= 4)); then compopt -o dirnames; fi
        elif [[ $type == 'file' ]]; then
            COMPREPLY=()
            if ((BASH_VERSINFO[0] >= 4)); then compopt -o default; fi
        elif [[ $type == 'plain' ]]; then
            COMPREPLY+=("${value#"$trim"}")
        fi
    done

    return 0
}

if ((BASH_VERSINFO[0] > 4 || (BASH_VERSINFO[0] == 4 && BASH_VERSINFO[1] >= 4))); then
    complete -o nosort -F _hcrctl_completion hcrctl
elif ((BASH_VERSINFO[0] == 4)); then
    complete -F _hcrctl_completion hcrctl
else
    # bash 3 has no compopt: readline's own file names stand in whenever hcrctl offers nothing.
    complete -o default -F _hcrctl_completion hcrctl
fi

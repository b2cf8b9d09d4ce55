# fish completion for hcrctl: printed by `hcrctl completion fish`.
# Each answer is TYPE,VALUE<tab>DESCRIPTION: split at the first comma only, so a
# description keeps its own commas.

function _hcrctl_completion
    set -l response (env _HCRCTL_COMPLETE=fish_complete COMP_WORDS=(commandline -cp) \
COMP_CWORD=(commandline -t) hcrctl)

    for completion in $response
        set -l metadata (string split -m 1 -- "," $completion)

        if test "$metadata[1]" = "dir"
            __fish_complete_directories $metadata[2]
        else if test "$metadata[1]" = "file"
            __fish_complete_path $metadata[2]
        else if test "$metadata[1]" = "plain"
            echo $metadata[2]
        end
    end
end

complete --no-files --command hcrctl --arguments "(_hcrctl_completion)"
